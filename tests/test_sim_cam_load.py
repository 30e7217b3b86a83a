"""A chain ending in a cam: the follower's weight and guide friction load the cam shaft in the
closed-loop kernel (seed 002 eq 3), checked against the cam component's own force law."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from servo_toolkit.components.cam.drive import CamDrive
from servo_toolkit.sim import Reference, build_model, default_controller, run
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.kernel import hermite, rhs
from servo_toolkit.sim.reference import fill

from .conftest import SCENES, build, variant

CAM = tomllib.loads((SCENES / "cam_follower.toml").read_text())


def _scene(tilt_deg, mu):
    return build(variant(CAM, drivetrain__0__gravity_tilt=f"{tilt_deg} deg",
                         drivetrain__0__guide_friction_coefficient=mu))


def _accel(scene, theta, w, volts=3.5):
    model = build_model(scene, None)
    P = fill(model, Reference.voltage(volts))
    x = np.zeros(model.nx)
    x[0] = x[2] = theta
    x[1] = x[3] = w
    dx, aux = np.empty(model.nx), np.empty(lo.NAUX)
    rhs(0.0, x, P, model.T, 0.0, dx, aux)
    return model, P, dx[1], aux


@pytest.mark.parametrize("theta", [0.3, 1.2, 2.0, 4.0, 5.6])
def test_tilt_changes_the_shaft_acceleration_by_the_weight_component(theta):
    """Frictionless guide: J(q) dw = ... + G sin(gamma) cos(beta) ds/dq, so tilting gravity
    from 0 to 170 deg changes J dw by exactly G sin(170 deg) ds/dq."""
    w = 5.0
    m0, P0, a0, _ = _accel(_scene(0, 0.0), theta, w)
    m1, _, a1, _ = _accel(_scene(170, 0.0), theta, w)
    j = hermite(m0.T, lo.T_J, P0, theta)[0]
    cam = _scene(0, 0.0).stages[0]
    d1 = CamDrive(cam, 0.0, 0.0, 1.0, 1.0, 0.0).law(theta).d1
    expected = 4.0 * math.sin(math.radians(170.0)) * float(d1)
    assert j * (a1 - a0) == pytest.approx(expected, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("theta", [0.3, 1.2, 4.0])
def test_shaft_equation_with_guide_friction_matches_the_follower_force_law(theta):
    """mu = 0.3, tilt 170 deg, fast enough that tanh(omega / w_s) = 1: the kernel's dw closes
    J dw + J' w^2 / 2 = N tau_shaft - (P - m a) ds/dq with the cam force P from
    CamDrive.follower_force at the follower's a = s'' w^2 + s' dw."""
    scene = _scene(170, 0.3)
    w = 30.0
    model, P, dw, aux = _accel(scene, theta, w)
    cam = scene.stages[0]
    drive = CamDrive(cam, 0.0, 0.0, 1.0, 1.0, 0.0)
    jet = drive.law(theta)
    d1, d2 = float(jet.d1), float(jet.d2)
    v, a = d1 * w, d2 * w * w + d1 * dw
    force, _ = drive.follower_force(np.array([theta]), np.array([v]), np.array([a]))
    j, dj = hermite(model.T, lo.T_J, P, theta)
    n = hermite(model.T, lo.T_N, P, theta)[0]
    m = scene.motor
    wm = n * w
    tau_shaft = aux[lo.AUX_TAU] - m.viscous_friction * wm - m.coulomb_friction * math.tanh(wm * P[lo.WS])
    lhs = j * dw + 0.5 * dj * w * w
    rhs_ = n * tau_shaft - (float(force[0]) - cam.follower_mass * a) * d1
    assert lhs == pytest.approx(rhs_, rel=1e-9, abs=1e-9 * abs(n * tau_shaft))


def test_closed_loop_torque_depends_on_tilt_and_friction():
    """The closed loop now has to carry the follower's weight: the peak motor torque of a
    hold run changes with the tilt (it did not when the kernel ignored it)."""
    peaks = []
    for tilt, mu in ((0, 0.001), (170, 0.3)):
        scene = _scene(tilt, mu)
        model = build_model(scene, default_controller(scene))
        res = run(model, Reference.ramp(2.0), 0.5, "auto")  # auto: the ramp crosses from the rise (largest inertia) into the dwell
        peaks.append(res.max_abs_motor_torque)
    # G sin(170 deg) max|ds/dq| = 4 N * 0.174 * 0.07 m = 0.049 N*m more to carry at most
    assert abs(peaks[1] - peaks[0]) > 0.1 * peaks[0], peaks


def test_the_automatic_step_reduces_a_run_that_went_non_finite():
    """A slow ramp of the cam drive through its dwell: the automatic step (0.0025 s, the
    duration / 200) goes non-finite at 0.395 s, where the stiffness along its records rose to
    |lambda| = 4.6e4 1/s. Before, method='auto' raised there; now it reads the stiffness from
    the run's finite records, reduces the step as for a run that leaves the stability region,
    says so in its choice, and agrees with the stiff reference solver."""
    scene = _scene(0, 0.001)
    model = build_model(scene, default_controller(scene))
    ref = Reference.ramp(0.2)
    auto = run(model, ref, 0.5, "auto")
    truth = run(model, ref, 0.5, "reference", rtol=1e-10, atol=1e-10)
    choice = auto.to_dict()["choice"]
    assert auto.to_dict()["method"] == "rk4" and auto.dt_s < 1e-4, choice
    assert "the run at dt = 0.0025 s went non-finite" in choice and "reduced to dt" in choice
    assert auto.max_abs_motor_torque == pytest.approx(truth.max_abs_motor_torque, rel=1e-3)
    assert auto.output_angle[-1] == pytest.approx(truth.output_angle[-1], rel=1e-3)
