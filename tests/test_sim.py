"""Simulation engine: convergence order, energy balance, agreement with the reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_toolkit import SimulationError, load_scene
from servo_toolkit.sim import (ModelOptions, Reference, build_model, default_controller, run,
                               simulate)
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.kernel import hermite
from servo_toolkit.sim.stability import REAL_LIMIT, max_stable_dt, rk4_amplification

from .conftest import SCENES, build, open_circuit_run, variant

AMP = math.radians(2.0)


@pytest.fixture(scope="module")
def ema():
    return load_scene(SCENES / "ema_reference.toml")


@pytest.fixture(scope="module")
def smooth_model(ema_dict_module):
    """No backlash, no Coulomb friction, no drivetrain loss, continuous controller: a smooth
    right-hand side (the friction's and the loss's smooth signs switch within a fraction of a
    millisecond at a reversal, where RK4 takes substeps: ``test_rk4_smooth_band``)."""
    scene = build(variant(ema_dict_module, motor__coulomb_friction="0 N*m", drivetrain__0__efficiency=1.0,
                          drivetrain__1__efficiency=1.0))
    return build_model(scene, default_controller(scene),
                       ModelOptions(backlash=False, controller_mode="continuous"))


@pytest.fixture(scope="module")
def ema_dict_module():
    import tomllib
    return tomllib.loads((SCENES / "ema_reference.toml").read_text())


def test_rk4_is_fourth_order(smooth_model):
    ref = Reference.sine(AMP, 8.0)
    q = [run(smooth_model, ref, 0.1, "rk4", dt, output_dt=1e-3).output_angle for dt in (4e-5, 2e-5, 1e-5)]
    ratio = np.max(np.abs(q[0] - q[1])) / np.max(np.abs(q[1] - q[2]))
    assert 13.0 < ratio < 19.0, ratio


def test_paper_scheme_is_first_order(smooth_model):
    ref = Reference.sine(AMP, 8.0)
    q = [run(smooth_model, ref, 0.1, "paper", dt, output_dt=1e-3).output_angle for dt in (2e-5, 1e-5, 5e-6)]
    ratio = np.max(np.abs(q[0] - q[1])) / np.max(np.abs(q[1] - q[2]))
    assert 1.6 < ratio < 2.5, ratio


def _energy(model, P, states):
    """Kinetic energy of both sides plus the spring potential (1/2) K(p) z^2."""
    e = []
    for x in states:
        jd = hermite(model.T, lo.T_J, P, x[0])[0]
        k = hermite(model.T, lo.T_K, P, x[0])[0]
        d, c = x[0] - x[2], P[lo.HALF_PLAY]
        z = d - c if d > c else d + c if d < -c else 0.0
        e.append(0.5 * jd * x[1] ** 2 + 0.5 * P[lo.JL] * x[3] ** 2 + 0.5 * k * z * z)
    return np.array(e)


def test_unforced_undamped_drivetrain_conserves_energy(ema_dict_module):
    """Open circuit (R -> 1e12 ohm), no friction, no hinge load, no structural damping, no
    stage losses (the gear and screw losses act on the torque the swinging rotor passes on):
    the variable inertia J(p) with its dJ/dp term and the elasto-backlash spring K(p) exchange
    energy without loss while the chain swings across the stroke."""
    scene = build(variant(ema_dict_module, motor__inductance="0 H",
                          motor__viscous_friction="0 N*m*s/rad", motor__coulomb_friction="0 N*m",
                          load__hinge_moment="0 N*m"))
    model = build_model(scene, None, ModelOptions(damping_ratio=0.0, efficiency=False))
    from servo_toolkit.sim.reference import fill
    P = fill(model, Reference.voltage(0.0))
    x0 = np.zeros(model.nx)
    x0[0], x0[1], x0[2], x0[3] = 0.002, 0.8, 0.0, 0.7   # in contact, both sides moving
    states = open_circuit_run(model, P, x0, 2e-5, 25000, every=25)
    e = _energy(model, P, states)
    q = states[:, 2]
    assert np.ptp(q) > 0.2                               # J(q) changes by several per cent
    assert np.ptp(e) / e[0] < 1e-6, np.ptp(e) / e[0]
    # the same run without the dJ/dq term would not conserve: the check can fail
    j = np.array([hermite(model.T, lo.T_J, P, x)[0] for x in states[:, 0]])
    assert np.ptp(j) / j.mean() > 0.02


def test_rk4_agrees_with_reference_on_ema_sampled(ema):
    model = build_model(ema, default_controller(ema))
    ref = Reference.sine(AMP, 8.0)
    a = run(model, ref, 0.04, "rk4", 2e-5, output_dt=1e-4)
    b = run(model, ref, 0.04, "reference", output_dt=1e-4, progress=False) \
        if False else run(model, ref, 0.04, "reference", output_dt=1e-4)
    err = np.max(np.abs(a.output_angle - b.output_angle)) / AMP
    assert err < 1e-6, err
    assert abs(a.max_abs_motor_torque - b.max_abs_motor_torque) < 0.02 * b.max_abs_motor_torque


def test_rk4_agrees_with_reference_on_ema_continuous(ema):
    model = build_model(ema, default_controller(ema), ModelOptions(controller_mode="continuous"))
    ref = Reference.sine(AMP, 8.0)
    a = run(model, ref, 0.25, "rk4", 5e-5, output_dt=1e-3)
    b = run(model, ref, 0.25, "reference", output_dt=1e-3)
    assert np.max(np.abs(a.output_angle - b.output_angle)) / AMP < 1e-6
    # the cam paper's scheme at the same step is visibly less accurate
    c = run(model, ref, 0.25, "paper", 5e-5, output_dt=1e-3)
    assert np.max(np.abs(c.output_angle - b.output_angle)) > 100 * np.max(np.abs(a.output_angle - b.output_angle))


def test_equilibrium_start_is_static(ema):
    """Holding mid-stroke against the 700 N*m hinge moment: nothing moves."""
    model = build_model(ema, default_controller(ema), ModelOptions(quantization=False))
    res = run(model, Reference(), 0.05, "rk4")
    assert np.max(np.abs(res.output_angle - model.q0)) < 1e-9
    n = hermite(model.T, lo.T_N, model.P, model.q0)[0]
    # hinge moment / (N Kt); N at p instead of q0 and the K'(p) z^2 / 2 term differ by < 1e-4
    assert res.motor_current[-1] == pytest.approx(700.0 / (n * 0.2), rel=1e-4)


def test_stability_polynomial_limits():
    assert abs(rk4_amplification(-REAL_LIMIT)) == pytest.approx(1.0, abs=1e-9)
    assert max_stable_dt(np.array([-1000.0 + 0j])) == pytest.approx(REAL_LIMIT / 1000, rel=1e-6)
    assert max_stable_dt(np.array([1j * 100.0])) == pytest.approx(2 * math.sqrt(2) / 100, rel=1e-6)


def test_rk4_refuses_unstable_step_and_auto_chooses(ema):
    # sampled at 0.1 ms the step never exceeds the sample time, which is stable here;
    # the continuous controller lets a user ask for 1 ms
    model = build_model(ema, default_controller(ema), ModelOptions(controller_mode="continuous"))
    ref = Reference.sine(AMP, 8.0)
    with pytest.raises(SimulationError, match="stability region"):
        run(model, ref, 0.01, "rk4", 1e-3)
    res = run(model, ref, 0.01, "auto")
    assert res.requested == "auto" and res.method == "rk4"
    assert res.dt_s * res.stability["max_abs_lambda"] <= 1.0 + 1e-9
    assert "RK4 with dt" in res.choice


def test_nonfinite_state_is_reported_with_time_and_name(ema):
    """Open loop, electrical pole -R/L = -1000 1/s, dt = 5 ms (z = -5, |R(z)| = 13.7) with the
    step check switched off: the state overflows (first the motor side's rate, which the
    current drives) and the run stops naming it. (Without
    Coulomb friction and the drivetrain's loss: friction that holds splits each step at the
    rotor's speed reversals, into shorter steps, and the smooth signs' band near rest is
    taken in substeps, which this slow rotor would never leave.)"""
    from dataclasses import replace
    lossless = replace(ema, stages=tuple(replace(s, efficiency=1.0) if hasattr(s, "efficiency") else s
                                         for s in ema.stages))
    model = build_model(lossless, None, ModelOptions(stroke_end="stop", friction="off"))
    with pytest.raises(SimulationError, match=r"non-finite state motor_side_rate_rad_s at t = 0.1\d+ s \(step 0.005 s\)"):
        run(model, Reference.voltage(1.0), 20.0, "rk4", 5e-3, check_stability=False)
    with pytest.raises(SimulationError, match="stability region"):
        run(model, Reference.voltage(1.0), 20.0, "rk4", 5e-3)


def test_simulate_open_loop_voltage_and_outputs(ema, tmp_path):
    res = simulate(ema, voltage=2.0, duration=0.02, method="rk4")
    assert res.to_dict()["t_final_s"] == pytest.approx(0.02)
    assert "open loop" in res.controller
    assert set(res.to_dict()) >= {"t_final_s", "final_state", "max_abs_motor_torque_Nm", "wall_s",
                                  "method", "dt_s"}
    for suffix in (".csv", ".npz"):
        path = res.save(tmp_path / f"run{suffix}")
        assert path.stat().st_size > 0
    data = np.load(tmp_path / "run.npz")
    assert np.allclose(data["output_angle_rad"], res.output_angle)


def test_cam_scene_open_loop_steady_speed():
    """Seed 002 check without the follower: 3.5 V on the motor alone gives
    (Kt u - R Mf) / (Ke Kt) = 13.36 rad/s with the Coulomb friction smoothed."""
    scene = load_scene(SCENES / "cam_follower.toml")
    import dataclasses
    cam = dataclasses.replace(scene.stages[0], follower_mass=1e-9, follower_weight=0.0)
    scene = dataclasses.replace(scene, stages=(cam,))
    res = simulate(scene, voltage=3.5, duration=3.0, method="rk4", dt=1e-3)
    assert res.motor_speed[-1] == pytest.approx(13.36, rel=2e-3)


def test_the_step_choice_and_the_run_say_where_their_eigenvalues_were_taken(ema):
    """The choice reports the fastest eigenvalue at the start, the run's line the fastest over
    the start and the states along the run: each names its own, and the figures it prints
    are of the state it names (|lambda dt| / dt is the start's |lambda|)."""
    import re
    model = build_model(ema, default_controller(ema))
    res = run(model, Reference.sine(AMP, 8.0), 0.05, "auto")
    m = re.search(r"\(at most the sample time\): \|lambda dt\| = (\S+) for the fastest eigenvalue at the start, "
                  r"\|lambda\| = (\S+) 1/s", res.choice)
    assert m, res.choice
    assert float(m.group(1)) / res.dt_s == pytest.approx(float(m.group(2)), rel=2e-3)
    line = [ln for ln in res.table().splitlines() if "fastest eigenvalue over the run" in ln]
    assert len(line) == 1
    assert f"|lambda| = {res.stability['max_abs_lambda']:.4g} 1/s at t = {res.stability['t_s']:.4g} s" in line[0]
    assert res.stability["max_abs_lambda"] >= float(m.group(2)) * (1 - 2e-3)
