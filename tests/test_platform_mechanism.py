"""Deflection platform of seed 003: eq 5, the corrected Jacobian, Lagrange dynamics, virtual power."""

import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.studies.mechanisms.dispatch import handles
from servo_toolkit.studies.run import run_study
from servo_toolkit.components.platform.model import PlatformModel
from servo_toolkit.studies.mechanisms.platform import ramp

from .conftest import SCENES


@pytest.fixture(scope="module")
def model():
    return PlatformModel.from_scene(load_scene(SCENES / "deflection_platform.toml"))


GRID = np.meshgrid(np.radians(np.linspace(-40, 40, 9)), np.radians(np.linspace(-40, 40, 9)))


def test_jacobian_is_the_derivative_of_eq5(model):
    a, b = GRID
    h = 1e-6
    jac = model.jacobian(a, b)
    fd_a = (model.inverse(a + h, b) - model.inverse(a - h, b)) / (2 * h)
    fd_b = (model.inverse(a, b + h) - model.inverse(a, b - h)) / (2 * h)
    assert np.allclose(jac[:, 0], fd_a, atol=1e-8) and np.allclose(jac[:, 1], fd_b, atol=1e-8)
    # the printed eq 7 (extra cos^2 and cos^3 of alpha) is not the derivative
    ry = model.platform.ratio_y
    c, t = np.cos(a), np.tan(b)
    printed22 = ry * c**3 / np.cos(b) ** 2 / (c**2 + t**2)
    assert np.abs(printed22 - fd_b[1]).max() > 0.1


def test_hessian_by_finite_differences(model):
    a, b = GRID
    h = 1e-6
    hess = model.hessian2(a, b)
    fd_a = (model.jacobian(a + h, b)[1] - model.jacobian(a - h, b)[1]) / (2 * h)
    fd_b = (model.jacobian(a, b + h)[1] - model.jacobian(a, b - h)[1]) / (2 * h)
    assert np.allclose(hess[:, 0], fd_a, atol=1e-7) and np.allclose(hess[:, 1], fd_b, atol=1e-7)


def test_alpha_independent_of_beta_and_beta_coupled(model):
    a, b = GRID
    th = model.inverse(a, b)
    assert np.allclose(th[0], model.platform.ratio_x * a)          # theta1 ignores beta
    assert np.all(model.jacobian(a, b)[0, 1] == 0)
    j21 = model.jacobian(a, b)[1, 0]
    off = (a != 0) & (b != 0)
    assert np.all(np.abs(j21[off]) > 1e-4) and np.all(j21[~off] == 0)  # theta2 depends on alpha
    # torques: motor 2 never sees Mx; motor 1 sees My only through the coupling J21/J22
    q = np.array([[0.3], [0.2]])
    qd = np.array([[0.05], [0.05]])
    qdd = np.zeros_like(q)
    t0 = model.motor_torques(q, qd, qdd, [[0.0], [0.0]])
    tx = model.motor_torques(q, qd, qdd, [[4.0], [0.0]])
    ty = model.motor_torques(q, qd, qdd, [[0.0], [4.0]])
    assert tx[1, 0] == pytest.approx(t0[1, 0], abs=1e-15)
    assert tx[0, 0] - t0[0, 0] == pytest.approx(4.0 / model.platform.ratio_x)
    jac = model.jacobian(0.3, 0.2)
    assert ty[0, 0] - t0[0, 0] == pytest.approx(-jac[1, 0] / jac[1, 1] * 4.0 / model.platform.ratio_x)


def test_lagrange_terms_match_christoffel_form(model):
    """h(q, qd) from the equivalent-element form equals the Christoffel form with dM/dq by FD."""
    q = np.array([0.35, -0.25])
    qd = np.array([0.7, -1.3])
    h = 1e-6
    dm = [(model.mass_matrix(*(q + h * e)) - model.mass_matrix(*(q - h * e))) / (2 * h) for e in np.eye(2)]
    chris = np.array([sum(0.5 * (dm[i][k, j] + dm[j][k, i] - dm[k][i, j]) * qd[i] * qd[j]
                          for i in range(2) for j in range(2)) for k in range(2)])
    assert np.allclose(model.coriolis(q[0], q[1], qd[0], qd[1]), chris, rtol=1e-6, atol=1e-12)
    eig = np.linalg.eigvalsh(model.mass_matrix(*q))
    assert eig.min() > 0


def test_virtual_power_balance_on_an_accelerating_path(model):
    """tau . theta' = dT/dt + M_load . q' along a path with q'' != 0."""
    t = np.linspace(0, 2, 4001)
    q = np.array([0.5 * np.sin(1.3 * t), 0.4 * np.sin(0.9 * t + 0.3)])
    qd = np.array([0.65 * np.cos(1.3 * t), 0.36 * np.cos(0.9 * t + 0.3)])
    qdd = np.array([-0.845 * np.sin(1.3 * t), -0.324 * np.sin(0.9 * t + 0.3)])
    load = np.array([[1.5], [-2.0]])
    tau = model.motor_torques(q, qd, qdd, load)
    thd = np.einsum("ij...,j...->i...", model.jacobian(q[0], q[1]), qd)
    ke = model.kinetic_energy(q[0], q[1], qd[0], qd[1])
    residual = np.sum(tau * thd, axis=0) - np.gradient(ke, t) - load[:, 0] @ qd
    assert np.abs(residual[2:-2]).max() < 1e-6 * np.abs(np.sum(tau * thd, axis=0)).max()


def test_ramp_study(model):
    scene = load_scene(SCENES / "deflection_platform.toml")
    assert handles(scene, "ramp")
    r = run_study(scene, "ramp")
    assert r.torques.shape == (4, 2, r.t.size)
    assert np.all(r.power_residual < 1e-4)
    assert math.degrees(r.q[0, -1]) == pytest.approx(30.0)
    # Mx = 4 N*m reaches motor 1 as 4 / ratio_x, not 6.36 * 4 as the seed's tables print
    assert r.torques[1, 0].mean() == pytest.approx(4.0 / 6.36, rel=1e-6)
    assert "power residual" in r.table() and len(r.to_dict()["cases"]) == 4


def test_motor_inertias_are_twice_a_and_b_of_eq14(model):
    """A and B of seed 003 eq 14 summed by hand from the scene file's numbers (kg*mm^2):
    A = [(z3/z4)^2 (I4 + 2 I8 + 2 I11 + I12) + I16] / 2 with I11 the pins' spin inertia,
    B = [(z1/z2)^2 (I5 + I7 + 2 I11o) + I15] / 2 with I11o the pins' inertia about O."""
    a = 0.5 * ((1 / 6.36) ** 2 * (2112.51 + 2 * 0.806 + 2 * 2.42 + 1267.677) + 8.244) * 1e-6
    b = 0.5 * ((1 / 3.2) ** 2 * (763.061 + 219.729 + 2 * 6.325) + 6.043) * 1e-6
    i1, i2 = model.motor_inertias
    assert i1 == pytest.approx(2 * a, rel=1e-12) and i2 == pytest.approx(2 * b, rel=1e-12)
    # and they enter M(q) as I1 J1'J1 + I2 J2'J2 on top of the platform's own inertia
    assert model.mass_matrix(0.0, 0.0) == pytest.approx(
        np.diag([10688.89e-6 + 2 * a * 6.36**2, 12600.333e-6 + 2 * b * 3.2**2]), rel=1e-12)


def test_a_torque_that_is_rounding_prints_as_zero():
    # unloaded, the alpha motor only balances terms that cancel: its torque is 0, not 1e-23 N*m
    res = run_study(load_scene(SCENES / "deflection_platform.toml"), "ramp")
    unloaded = [i for i, m in enumerate(res.load_moments) if not np.any(m)][0]
    assert np.all(res.torques[unloaded, 0] == 0.0) and not np.any(np.signbit(res.torques[unloaded, 0]))
    row = res.table().splitlines()[2 + unloaded]
    assert "e-2" not in row and "-0" not in row.split()[2]
    assert res.to_dict()["cases"][unloaded]["tau1_range_Nm"] == [0.0, 0.0]
    # a torque well above rounding stays as computed
    assert np.max(res.torques[unloaded, 1]) > 1e-7
