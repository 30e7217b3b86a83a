"""Feedforward from the commanded trajectory: off by default, outside the loop, and what the
model-based torque feedforward does on the reference EMA's 8 Hz, 2 deg sine."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.loop.controller import Feedforward
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for, simulate
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.studies.time.run import simulate_study

from .conftest import SCENES

FF_SLOTS = [lo.FF_ON, lo.FF_KV, lo.FF_KA, lo.FF_MODEL, lo.FF_JSCALE, lo.FF_SPEED, lo.FF_LEAD]


@pytest.fixture(scope="module")
def ema():
    scene = load_scene(SCENES / "ema_reference.toml")
    controller, _ = controller_for(scene)
    return scene, controller


@pytest.fixture(scope="module")
def sine_errors(ema):
    """Tracking error of the default sine run with the feedforward off, on, and with its
    inertia off by -30 %, +30 % and -100 % (no inertial term)."""
    scene, _ = ema
    runs = {"off": "off", "on": "model", "gains": "gains"}
    runs.update({s: Feedforward(model=True, inertia_scale=s) for s in (0.7, 1.3, 0.0)})
    out = {}
    for name, ff in runs.items():
        r = simulate_study(scene, feedforward=ff)
        assert r.start_transient_s == pytest.approx(0.25)  # the sine's first two periods, as stated
        settled = r.times > r.start_transient_s
        out[name] = (r.output_angle - r.reference_angle)[settled]
        out["start_" + str(name)] = (r.output_angle - r.reference_angle)[~settled]
        out["notes_" + str(name)] = r.notes
    return out


def _peak(e):
    return float(np.max(np.abs(e)))


def test_off_by_default_packs_nothing(ema):
    scene, controller = ema
    assert controller.feedforward is None
    plain = build_model(scene, controller)
    assert not np.any(plain.P[FF_SLOTS])
    inactive = build_model(scene, replace(controller, feedforward=Feedforward()))
    np.testing.assert_array_equal(inactive.P, plain.P)
    on = build_model(scene, replace(controller, feedforward=Feedforward(model=True)))
    assert on.P[lo.FF_ON] == 1.0 and on.P[lo.FF_MODEL] == 1.0 and on.P[lo.FF_SPEED] == 1.0
    assert on.P[lo.FF_LEAD] == pytest.approx(0.5 * controller.sample_time)
    assert any("feedforward" in n for n in on.notes) and not any("feedforward" in n for n in plain.notes)


def test_linearized_model_identical_with_and_without_feedforward(ema):
    """The feedforward enters from the command only: the compiled closed loop (continuous
    controller, so the motion controller is in the right-hand side) linearized at one state
    and time of a sine has the same Jacobian, and so the same eigenvalues, with and without
    it, while the feedforward changes the right-hand side there (it adds current)."""
    from servo_toolkit.sim.kernel import rhs
    from servo_toolkit.sim.stability import jacobian
    scene, controller = ema
    opts = ModelOptions(controller_mode="continuous", chain="two_mass", friction="off")
    ref = Reference.sine(math.radians(0.2), 8.0)
    t = 1.0 / 32.0  # the sine's peak: r'' at its largest
    jac, rates = [], []
    for ff in (None, Feedforward(velocity=0.3, acceleration=0.01, model=True)):
        model = build_model(scene, replace(controller, feedforward=ff), opts)
        P = fill(model, ref)
        x = initial_state(model, P)
        dx, aux = np.empty(model.nx), np.empty(lo.NAUX)
        rhs(t, x, P, model.T, 0.0, dx, aux)
        # no clamp (the current holds the 700 N*m hinge moment, about 25 A): the loop is linear here
        assert abs(aux[lo.AUX_IREF]) < 0.9 * scene.motor.current_limit and abs(aux[lo.AUX_V]) < scene.motor.voltage_limit
        rates.append(dx.copy())
        jac.append(jacobian(model, P, x, t, x[4]))
    assert not np.allclose(rates[0], rates[1])  # the feedforward acts
    np.testing.assert_allclose(jac[1], jac[0], rtol=1e-7, atol=1e-9 * np.max(np.abs(jac[0])))
    e0, e1 = (np.sort_complex(np.linalg.eigvals(j)) for j in jac)
    np.testing.assert_allclose(e1, e0, rtol=1e-6, atol=1e-6 * np.max(np.abs(e0)))


def test_bad_feedforward_names_the_option(ema):
    scene, controller = ema
    with pytest.raises(SceneError) as err:
        simulate(scene, controller, duration=0.01, feedforward="velocity")
    assert err.value.key == "feedforward"
    with pytest.raises(SceneError):
        simulate(scene, None, voltage=1.0, duration=0.01, feedforward="model")
    with pytest.raises(ValueError):
        Feedforward(inertia_scale=-1.0)


def test_model_feedforward_cuts_the_8hz_sine_error_fivefold(sine_errors):
    """Peak error once the start's transient has passed (about 11x here: 2.3 -> 0.21 deg)."""
    off, on = _peak(sine_errors["off"]), _peak(sine_errors["on"])
    assert math.degrees(off) > 2.0  # the feedback alone: about 2.3 deg
    assert on <= off / 5.0
    assert any("feedforward" in n for n in sine_errors["notes_on"])


def test_designed_gains_cut_the_8hz_sine_error(sine_errors):
    """The designed velocity and acceleration gains (Ka = J / (N Kt), Kv = (b N^2 + c) / (N Kt)
    at q0) with the speed reference: the peak error falls several times too."""
    assert _peak(sine_errors["gains"]) <= _peak(sine_errors["off"]) / 5.0
    assert any("velocity" in n and "acceleration" in n for n in sine_errors["notes_gains"])


def test_inertia_error_degrades_as_first_order_sensitivity_predicts(sine_errors):
    """The error is linear in the missing feedforward current to first order: with the
    feedforward's inertia scaled by 1 + d, e(d) = e(0) + d (e(0) - e(-1)), e(-1) the error
    without the inertial term."""
    e0, e_none = sine_errors["on"], sine_errors[0.0]
    sens = e0 - e_none
    for d, key in ((-0.3, 0.7), (0.3, 1.3)):
        measured = sine_errors[key]
        predicted = e0 + d * sens
        assert _peak(measured) == pytest.approx(_peak(predicted), rel=0.05)
        # the whole trace, not only its peak, follows the prediction
        assert _peak(measured - predicted) < 0.05 * _peak(d * sens)
        # and still beats the feedback alone by far
        assert _peak(measured) < 0.3 * _peak(sine_errors["off"])
    # the inertia's share is real: without it the error is several times the nominal one
    assert _peak(e_none) > 2 * _peak(e0)


def test_the_batch_runs_a_feedforward_variant_as_its_single_run(ema):
    """Variants with and without the model-based feedforward (one with its inertia off by
    20 %): the batch on one and two threads gives each variant's single run to the bit, and
    carries the feedforward."""
    from .test_batch import assert_as_single_runs
    scene, controller = ema
    ref = Reference.sine(math.radians(2.0), 8.0)
    opts = ModelOptions(chain="two_mass")
    plain = build_model(scene, controller, opts)
    on = build_model(scene, replace(controller, feedforward=Feedforward(model=True)), opts)
    out = []
    for model in (plain, on):
        P = np.array([fill(model, ref)] * 3)
        assert P[0, lo.FF_ON] == (model is on)
        P[2, lo.FF_JSCALE] *= 1.2
        X0 = np.array([initial_state(model, p) for p in P])
        X = assert_as_single_runs(P, model.T[None], np.zeros(3, dtype=np.int64), X0,
                                  int(round(model.sample_time / 1e-4)), 200, 1e-4, threads=(1, 2))[0]
        out.append(X)
    assert not np.allclose(out[0], out[1])  # the feedforward is carried, not dropped
    assert not np.array_equal(out[1][2], out[1][0])  # and each variant's own


def test_cli_simulate_feedforward(capsys):
    """``simulate --feedforward model``: the JSON run with the feedforward in its notes and a
    smaller error than the feedback alone (its peak includes the start's transient); a
    seed-mechanism study refuses the option (exit 2, one line naming it)."""
    import json

    from servo_toolkit.cli import main
    assert main(["simulate", str(SCENES / "ema_reference.toml"), "--feedforward", "model", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["max_abs_tracking_error_deg"] < 2.0
    # the figure after the start's transient is stated with its window (two periods of 8 Hz)
    assert out["start_transient_s"] == pytest.approx(0.25)
    assert out["max_abs_tracking_error_after_start_deg"] < 0.5
    assert any("feedforward" in n for n in out["notes"])
    code = main(["simulate", str(SCENES / "cam_follower.toml"), "--study", "constant_speed", "--feedforward", "model"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--feedforward" in err[0]
