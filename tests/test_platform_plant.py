"""Deflection platform (seed 003) as a linear MIMO plant: checked against the inverse
dynamics, a linearization of the kinetic energy by finite differences, the nonlinear
Lagrange model in time, and the coupling the kinematics predicts."""

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from servo_toolkit import SceneError, load_scene
from servo_toolkit.components.platform.model import PlatformModel
from servo_toolkit.plant.platform import PLATFORM_PLANT_UNITS, platform_plant

from .conftest import SCENES

POINTS = [(0.0, 0.0), (0.3, 0.0), (0.0, 0.3), (0.35, -0.25), (-0.5, 0.4)]


@pytest.fixture(scope="module")
def scene():
    return load_scene(SCENES / "deflection_platform.toml")


@pytest.fixture(scope="module")
def model(scene):
    return PlatformModel.from_scene(scene)


def _accel_gain(sys):
    """lim s^2 G(s) of the double integrator, tau -> (alpha, beta)'', from the frequency response."""
    s = 1e-3j
    return np.real(s**2 * sys(s))[:2, :2]


def test_signals_named_and_units(scene):
    sys = platform_plant(scene, (0.2, 0.1), loads=True)
    assert sys.input_labels == ["tau1", "tau2", "Mx", "My"]
    assert sys.output_labels == ["alpha", "beta", "theta1", "theta2"]
    assert sys.state_labels == ["alpha", "beta", "alpha_dot", "beta_dot"]
    assert set(sys.input_labels + sys.output_labels + sys.state_labels) <= set(PLATFORM_PLANT_UNITS)
    assert platform_plant(scene).ninputs == 2
    # at rest, no gravity, no stiffness: four poles at the origin
    assert np.allclose(sys.poles(), 0.0)


@pytest.mark.parametrize("q0", POINTS)
def test_low_frequency_gain_inverts_motor_torques(model, q0):
    """tau -> q'' of the plant is the inverse of the inverse dynamics motor_torques (at rest,
    no load) for a small acceleration."""
    sys = platform_plant(model, q0, loads=True)
    q = np.array(q0, dtype=float)[:, None]
    zero = np.zeros((2, 1))
    eps = 1e-3
    torque_per_acc = np.column_stack([model.motor_torques(q, zero, eps * e[:, None], zero)[:, 0] / eps
                                      for e in np.eye(2)])
    gain = _accel_gain(sys[:2, :2])
    assert np.allclose(gain @ torque_per_acc, np.eye(2), atol=1e-9)
    # a resisting load moment is balanced by the motor torques motor_torques gives for it
    load = np.array([1.5, -2.0])
    tau = model.motor_torques(q, zero, zero, load[:, None])[:, 0]
    acc = np.real(1e-6 * sys(1e-3j))[:2, :] @ np.concatenate([tau, load])
    assert np.allclose(acc, 0.0, atol=1e-9 * np.abs(tau).max())


@pytest.mark.parametrize("q0", POINTS)
def test_matches_finite_difference_linearization_of_the_energy(model, q0):
    """B from M = d2T/dqd2 and J = d(theta)/dq, both by finite differences of the model's
    kinetic energy and motor angles (not of mass_matrix / jacobian)."""
    a0, b0 = q0
    h = 1e-4
    m = np.empty((2, 2))
    for i, ei in enumerate(np.eye(2)):
        for j, ej in enumerate(np.eye(2)):
            ke = lambda v: float(model.kinetic_energy(a0, b0, *v))
            m[i, j] = (ke(h * (ei + ej)) - ke(h * (ei - ej)) - ke(h * (ej - ei)) + ke(-h * (ei + ej))) / (4 * h * h)
    jac = np.column_stack([(model.inverse(*(np.array(q0) + h * e)) - model.inverse(*(np.array(q0) - h * e)))
                           / (2 * h) for e in np.eye(2)])
    sys = platform_plant(model, q0)
    assert np.allclose(sys.B[2:], np.linalg.solve(m, jac.T), rtol=1e-6, atol=1e-9)
    assert np.allclose(sys.C[2:, :2], jac, rtol=1e-6, atol=1e-9)
    # A: the nonlinear right-hand side M^-1 (J' tau - h) differentiated at rest
    tau0 = np.zeros(2)

    def rhs(x):
        mm = model.mass_matrix(x[0], x[1])
        force = model.jacobian(x[0], x[1]).T @ tau0 - model.coriolis(x[0], x[1], x[2], x[3])
        return np.concatenate([x[2:], np.linalg.solve(mm, force)])
    x0 = np.array([a0, b0, 0.0, 0.0])
    a_fd = np.column_stack([(rhs(x0 + h * e) - rhs(x0 - h * e)) / (2 * h) for e in np.eye(4)])
    assert np.allclose(sys.A, a_fd, atol=1e-9)


def test_small_torques_follow_the_nonlinear_lagrange_model(model):
    """Torque steps from rest: the nonlinear M(q) q'' + h = J' tau (solve_ivp) and the linear
    plant differ at second order in the motion, so a 4x smaller torque leaves a ~4x smaller
    relative error (and a small one)."""
    q0 = (0.35, -0.25)
    t = np.linspace(0, 0.2, 41)
    plant = platform_plant(model, q0)

    def relative_errors(tau):
        def fun(_t, x):
            mm = model.mass_matrix(x[0], x[1])
            force = model.jacobian(x[0], x[1]).T @ tau - model.coriolis(x[0], x[1], x[2], x[3])
            return np.concatenate([x[2:], np.linalg.solve(mm, force)])
        sol = solve_ivp(fun, (0, t[-1]), [*q0, 0.0, 0.0], t_eval=t, rtol=1e-12, atol=1e-14)
        lin = np.asarray(ct.forced_response(plant, t, np.outer(tau, np.ones_like(t))).outputs)
        moved = sol.y[:2] - np.array(q0)[:, None]
        theta = model.inverse(sol.y[0], sol.y[1]) - model.inverse(*q0)[:, None]
        return (np.abs(lin[:2] - moved).max() / np.abs(moved).max(),
                np.abs(lin[2:] - theta).max() / np.abs(theta).max())
    big = relative_errors(np.array([0.004, -0.003]))
    small = relative_errors(np.array([0.001, -0.00075]))
    for b, s in zip(big, small):
        assert s < 0.01 and b / s == pytest.approx(4.0, rel=0.15)


def test_coupling(model):
    """theta1 = rx alpha: motor 1 drives alpha alone kinematically. On the axes (alpha0 = 0
    or beta0 = 0) J21 = 0 and, with Ixy = 0, M is diagonal: tau2 does not move alpha and
    tau1 does not move beta. Off the axes the small arch couples them both ways."""
    rx = model.platform.ratio_x
    for q0 in [(0.0, 0.0), (0.3, 0.0), (0.0, 0.3)]:
        g = _accel_gain(platform_plant(model, q0))
        assert g[0, 1] == 0.0 and g[1, 0] == 0.0, q0
    g = _accel_gain(platform_plant(model, (0.35, -0.25)))
    assert abs(g[0, 1]) > 1e-3 * abs(g[0, 0]) and abs(g[1, 0]) > 1e-3 * abs(g[1, 1])
    sys = platform_plant(model, (0.35, -0.25))
    assert np.array_equal(sys.C[2], np.array([rx, 0.0, 0.0, 0.0]))


def test_bad_input(scene):
    with pytest.raises(ValueError, match="q0"):
        platform_plant(scene, (0.0, np.pi / 2))
    with pytest.raises(SceneError, match="crossed-arch"):
        platform_plant(load_scene(SCENES / "cam_follower.toml"))
