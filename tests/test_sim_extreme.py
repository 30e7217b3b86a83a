"""Stiff and extreme cases (issue item 7): each matches the reference within the stated
tolerance or raises a clear SimulationError; none returns NaN.

Every case runs on two paths: the continuous motion controller with the fallback cascade
(the reference is a single ``solve_ivp`` call), and the default path, the sampled controller
with the designed cascade (``loop.design``; the reference restarts at every sample). The
reference is LSODA at rtol = atol = 1e-10; the integrator under test is ``auto``. The chain
is lossless here (``efficiency=False``): the drivetrain's losses and their accuracy are
checked in test_sim_efficiency.py.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from servo_toolkit import SimulationError
from servo_toolkit.sim import ModelOptions, Reference, build_model, default_controller, run
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.simulate import controller_for

from .conftest import SCENES, build, variant

AMP = math.radians(2.0)
BASE = tomllib.loads((SCENES / "ema_reference.toml").read_text())


@pytest.fixture(params=["continuous-fallback", "sampled-designed"])
def path(request):
    return request.param


def _model(scene, path, **opts):
    if path == "continuous-fallback":
        return build_model(scene, default_controller(scene),
                           ModelOptions(controller_mode="continuous", efficiency=False, **opts))
    controller, source = controller_for(scene)
    assert source == "loop.design"
    return build_model(scene, controller, ModelOptions(controller_mode="sampled", efficiency=False, **opts))


def _compare(scene, ref, duration, tol, path="continuous-fallback", **opts):
    model = _model(scene, path, **opts)
    a = run(model, ref, duration, "auto", output_dt=1e-3)
    b = run(model, ref, duration, "reference", output_dt=1e-3)
    assert np.all(np.isfinite(a.states)) and np.all(np.isfinite(b.states))
    scale = max(abs(ref.amplitude), np.ptp(b.output_angle) / 2, 1e-3)
    err = np.max(np.abs(a.output_angle - b.output_angle)) / scale
    assert err < tol, (err, a.choice)
    return a, b


def test_inductance_1uH_auto_reduces_the_step(path):
    scene = build(variant(BASE, motor__inductance="1 uH"))
    a, _ = _compare(scene, Reference.sine(AMP, 8.0), 0.05, 1e-6, path)
    assert a.dt_s < 1e-5 and a.stability["max_abs_lambda"] > 1e5


def test_stiffness_x1000(path):
    a, _ = _compare(build(BASE), Reference.sine(AMP, 8.0), 0.1, 1e-6, path, stiffness_scale=1000.0)
    # drivetrain mode sqrt(K (1/J_d + 1/J_L)) = sqrt(3.4e7 * (1/4.4 + 1)) = 6.46e3 rad/s
    assert a.stability["max_abs_lambda"] > 6e3


@pytest.mark.parametrize("play_deg, tol", [(0.0, 1e-6), (2.0, 5e-4)])
def test_zero_and_large_backlash_without_preload(play_deg, tol, path):
    """No hinge moment: with 2 deg of play the load flies freely through the play and hits
    it at every reversal. The contact moment is continuous at engagement (ElastoBacklash),
    so the fixed steps straddling a contact cost little: 8.5e-5 of the amplitude measured at
    the automatic step (the discontinuous max(k z + d z', 0) law gave 1.6e-2)."""
    scene = build(variant(BASE, load__hinge_moment="0 N*m"))
    _compare(scene, Reference.sine(math.radians(5.0), 4.0), 0.3, tol, path, play=math.radians(play_deg))


def test_zero_load_inertia(path):
    """Only the output shaft stays on the load side: a fast local mode."""
    scene = build(variant(BASE, load__inertia="0 kg*m^2"))
    a, _ = _compare(scene, Reference.sine(AMP, 8.0), 0.1, 1e-5, path)
    assert a.stability["max_abs_lambda"] > 5e3


def test_twenty_times_load_inertia(path):
    scene = build(variant(BASE, load__inertia="20 kg*m^2"))
    _compare(scene, Reference.sine(AMP, 8.0), 0.3, 1e-6, path)


def test_current_saturation_held_for_the_whole_run(path):
    """A 20 A drive on the 20 deg step: saturated from the first sample to the last. The
    sampled controller's integrator is back-calculated at the clamp (it keeps no excess), so
    the current stays at the limit only while the speed loop's proportional part alone asks
    for more; the scene's 60 A accelerates the motor enough within 1 ms to pull it off (12.6 A
    at 1 ms, measured), the 20 A drive's does not."""
    scene = build(variant(BASE, motor__current_limit="20 A"))
    a, b = _compare(scene, Reference.step(math.radians(20.0), offset=math.radians(-10.0)), 0.02, 1e-6, path)
    ilim = scene.motor.current_limit
    assert np.all(np.abs(b.current_reference[1:]) == pytest.approx(ilim))
    assert np.all(np.abs(a.current_reference[1:]) == pytest.approx(ilim))
    for res in (a, b):  # both runs state that they were saturated
        assert any(f"its current limit {ilim:g} A for" in s for s in res.notes), res.notes


def test_stroke_end_raises_or_stops():
    scene = build(BASE)
    ramp = Reference.ramp(math.radians(200.0), offset=math.radians(20.0))
    model = build_model(scene, default_controller(scene), ModelOptions(controller_mode="continuous"))
    with pytest.raises(SimulationError, match="stroke end reached at t = "):
        run(model, ramp, 0.5, "auto")
    with pytest.raises(SimulationError, match="stroke end"):
        run(model, ramp, 0.5, "reference")
    a, b = _compare(scene, ramp, 0.3, 1e-3, stroke_end="stop")
    assert b.output_angle.max() > math.radians(30.0)          # it did hit the stop
    assert b.output_angle.max() < math.radians(31.0)          # and the stop held


def test_a_run_at_the_motor_limits_says_so():
    # 1 V cannot hold the 700 N*m hinge moment: at stall that takes R M / (N Kt) = 12.6 V
    # (N = 52/24 * 2 pi r / lead = 138.9 at q = 0 for the rod parallel to the screw; still
    # 10.9 V with the back-driven efficiency 0.862), so the voltage is pinned at its limit for
    # the whole run, which the result must state
    scene = build(variant(BASE, motor__voltage_limit="1 V"))
    motor = scene.motor
    n = 52 / 24 * 2 * math.pi * 0.051 / 0.005
    assert 0.8 * motor.resistance * 700.0 / (n * motor.torque_constant) > 10 * motor.voltage_limit
    model = build_model(scene, default_controller(scene), ModelOptions(controller_mode="continuous"))
    res = run(model, Reference.sine(AMP, 8.0), 0.05, "rk4", output_dt=1e-3)
    assert np.all(np.abs(res.motor_voltage[1:]) == pytest.approx(motor.voltage_limit))
    note = [s for s in res.notes if "voltage limit" in s]
    assert len(note) == 1 and "1 V for 50 ms of the 50 ms run" in note[0], res.notes
    assert res.to_dict()["notes"] == list(res.notes)
    # within its limits a run carries no such note
    base = build(BASE)
    quiet = run(build_model(base, default_controller(base), ModelOptions(controller_mode="continuous")),
                Reference.sine(AMP, 8.0), 0.05, "rk4", output_dt=1e-3)
    assert np.max(np.abs(quiet.motor_voltage)) < base.motor.voltage_limit
    assert np.max(np.abs(quiet.motor_current)) < base.motor.current_limit
    assert not [s for s in quiet.notes if "the motor was at" in s], quiet.notes


@pytest.mark.parametrize("chain", ["two_mass", "full"])
def test_a_start_deflected_beyond_the_stroke_is_refused(chain):
    # a housing 1e3 times softer carries the 700 N*m hinge moment only wound up by
    # 700 / 1.6968 = 412.5 deg: the members before it would start far outside the stroke
    # (+-30 deg), where the drivetrain's kinematics are not known; the run refuses to start
    scene = build(variant(BASE, drivetrain__3__stiffness="1.6968 N*m/deg"))
    model = build_model(scene, default_controller(scene), ModelOptions(controller_mode="continuous", chain=chain))
    with pytest.raises(SimulationError, match=r"outside the stroke.*load.hinge_moment") as err:
        run(model, Reference.sine(AMP, 8.0), 0.01, "rk4")
    assert "\n" not in str(err.value)
    deflection = float(str(err.value).split("deflected by ")[1].split(" deg")[0])
    assert deflection == pytest.approx(700.0 / 1.6968, rel=0.02)
    # the batched Monte Carlo and the tolerance runs start from the same equilibrium
    with pytest.raises(SimulationError, match="outside the stroke"):
        initial_state(model, fill(model, Reference.sine(AMP, 8.0)))


def test_a_travel_output_leaving_its_stroke_is_told_in_mm():
    """A carriage driven past its stroke: the refusal reads the travel in mm, not metres shown
    as degrees."""
    from servo_toolkit import load_scene
    scene = load_scene(SCENES / "linear_roller_screw_actuator.toml")
    assert scene.drivetrain.output_is_linear
    lo_q, hi_q = scene.drivetrain.stroke
    model = build_model(scene, default_controller(scene), ModelOptions(controller_mode="continuous"))
    ramp = Reference.ramp(20 * (hi_q - lo_q), offset=0.5 * (lo_q + hi_q))
    with pytest.raises(SimulationError, match=r"stroke end reached at t = [0-9.e-]+ s: output travel "
                                              r"-?[0-9.]+ mm outside \[") as err:
        run(model, ramp, 1.0, "auto")
    assert f"[{lo_q * 1e3:.1f}, {hi_q * 1e3:.1f}] mm" in str(err.value)
