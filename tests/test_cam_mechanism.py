"""Cam drive of seed 002: law, inertia, load torque, clearance, both solvers."""

import math
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit import SimulationError, load_scene
from servo_toolkit.components.cam import modified_constant_velocity
from servo_toolkit.mechanisms import handles, run_study
from servo_toolkit.mechanisms import cam_kernels
from servo_toolkit.mechanisms.cam import CamDrive, clearance_hysteresis, constant_speed
from servo_toolkit.mechanisms.cam_voltage import accurate, constant_voltage, discrete_scheme

from .conftest import SCENES

A = 0.035


@pytest.fixture(scope="module")
def drive():
    return CamDrive.from_scene(load_scene(SCENES / "cam_follower.toml"))


def test_law_continuity_derivatives_and_periodicity():
    eps = 1e-7
    for k in range(9):  # every segment boundary, incl. 0 and 2 pi
        b = k * math.pi / 4
        jl = modified_constant_velocity(np.array([b - eps]), A)
        jh = modified_constant_velocity(np.array([b + eps]), A)
        assert abs(jh.value[0] - jl.value[0]) < 1e-6 * A, k
        assert abs(jh.d1[0] - jl.d1[0]) < 1e-5 * A, k
        assert abs(jh.d2[0] - jl.d2[0]) < 1e-5 * A, k  # the law is even C2
    th = np.linspace(0.01, 2 * math.pi - 0.01, 997)
    j = modified_constant_velocity(th, A)
    h = 1e-6
    fd1 = (modified_constant_velocity(th + h, A).value - modified_constant_velocity(th - h, A).value) / (2 * h)
    fd2 = (modified_constant_velocity(th + h, A).d1 - modified_constant_velocity(th - h, A).d1) / (2 * h)
    assert np.allclose(fd1, j.d1, atol=1e-8) and np.allclose(fd2, j.d2, atol=1e-6)
    assert np.allclose(modified_constant_velocity(th + 2 * math.pi, A).value, j.value, atol=1e-12)
    # conjugate (double-roller) cam: s(theta) + s(theta + pi) = stroke
    assert np.allclose(j.value + modified_constant_velocity(th + math.pi, A).value, 1.5 * math.pi * A)
    assert j.value.max() == pytest.approx(1.5 * math.pi * A, rel=1e-3)


def test_equivalent_inertia_matches_seed_numbers(drive):
    th = np.linspace(0, 2 * math.pi, 20001)
    j, dj = drive.inertia(th)
    assert j.min() == pytest.approx(4.41e-5, rel=1e-6)
    assert j.max() == pytest.approx(2.004e-3, rel=1e-3)
    h = 1e-6
    assert np.allclose(dj[1:-1], (drive.inertia(th[1:-1] + h)[0] - drive.inertia(th[1:-1] - h)[0]) / (2 * h),
                       atol=1e-7)


def test_friction_matches_corrected_eq1_when_all_terms_positive(drive):
    cam = replace(drive.cam, guide_friction_coefficient=0.2, gravity_tilt=math.radians(60),
                  gravity_heading=math.radians(200))
    d = replace(drive, cam=cam)
    th, v, a = 0.5, 0.3, 2.0  # rising, accelerating: P > 0
    p, f = d.follower_force(th, v, a)
    gx, gy, gz = d.gravity()
    tan_a = float(d.pressure_tangent(th, 1.0))
    m, mu, g = cam.follower_mass, cam.guide_friction_coefficient, cam.follower_weight
    gamma, beta = cam.gravity_tilt, cam.gravity_heading
    eq1 = mu * ((m * a - g * math.sin(gamma) * math.cos(beta)) * tan_a + g * math.sin(gamma) * math.sin(beta)
                + abs(g * math.cos(gamma))) / (1 - mu * tan_a)
    assert float(p) > 0 and float(p) * tan_a + gy > 0
    assert float(f) == pytest.approx(eq1, rel=1e-12)
    # the printed denominator (1 - tan alpha) gives a different number
    assert abs(float(f) - eq1 * (1 - mu * tan_a) / (1 - tan_a)) > 1e-3


def test_load_torque_cycle_integrals(drive):
    """Over a turn at constant speed gravity and follower inertia do no net work; friction does."""
    r = constant_speed(drive, 1.0, 1e-4, [0.0, math.radians(170)])
    dth = np.diff(r.theta)
    work = lambda y: np.sum(0.5 * (y[..., 1:] + y[..., :-1]) * dth, axis=-1)
    assert np.all(np.abs(work(r.gravity)) < 1e-6)
    assert np.all(np.abs(work(r.inertial)) < 1e-7)
    assert np.all(work(r.friction) > 0)
    # tilted: gravity dominates the ripple (seed section 4.1)
    assert np.ptp(r.torque[1]) > 5 * np.ptp(r.torque[0])
    assert np.degrees(np.abs(r.pressure_angle)).max() == pytest.approx(30.0, abs=0.05)


def test_clearance_hysteresis_is_a_play_operator():
    t = np.linspace(0, 1, 401)
    s = np.sin(2 * math.pi * t)
    out = clearance_hysteresis(s, 0.1)
    assert np.all(np.abs(out - s) <= 0.1 + 1e-12)
    assert out.max() == pytest.approx(1 - 0.1, abs=1e-3) and out.min() == pytest.approx(-1 + 0.1, abs=1e-3)
    assert np.array_equal(clearance_hysteresis(s, 0.0), s)


def test_kernels_match_vectorized_model(drive):
    p = cam_kernels.pack(drive)
    for th in np.linspace(0, 2 * math.pi, 37):
        j = drive.law(th)
        assert np.allclose(cam_kernels.law(th, A), (j.value, j.d1, j.d2), atol=1e-15)
        force, f = drive.follower_force(th, 0.2, -0.7)
        kf, kfr = cam_kernels.friction(p, float(j.value), float(j.d1), 1.0, 0.4 * -0.7 - p[3], 0.0)
        assert kf == pytest.approx(float(force), rel=1e-12) and kfr == pytest.approx(float(f), rel=1e-12)


@pytest.mark.parametrize("solver", ["accurate", "seed", "corrected"])
def test_follower_removed_settles_at_13_36(drive, solver):
    bare = drive.without_follower()
    run = accurate(bare, 3.5, 0.6) if solver == "accurate" else discrete_scheme(bare, 3.5, 0.6, 1e-3, solver)
    assert run.omega[-1] == pytest.approx(13.36, abs=0.005)


def test_energy_balance_of_accurate_solution(drive):
    """Input electrical-mechanical power = dKE/dt + losses (friction, gravity = 0 flat)."""
    run = accurate(drive, 3.5, 0.5, t_eval=np.linspace(0, 0.5, 5001))
    j, _ = drive.inertia(run.theta)
    ke = 0.5 * j * run.omega**2
    jet = drive.law(run.theta)
    v = jet.d1 * run.omega
    dw = np.gradient(run.omega, run.t)
    a = jet.d2 * run.omega**2 + jet.d1 * dw
    _, f = drive.follower_force(run.theta, v, a)
    p_in = drive.torque_constant * run.current * run.omega
    p_loss = drive.shaft_friction * run.omega + f * np.abs(v)
    residual = np.gradient(ke, run.t) - (p_in - p_loss)
    assert np.abs(residual[5:-5]).max() < 2e-3 * np.abs(p_in).max()


def test_constant_voltage_convergence_and_difference(drive):
    r = constant_voltage(drive, 3.5, 0.4, 1e-3, refinements=2, window=0.3)
    assert np.all(r.orders("corrected") > 0.8) and np.all(r.orders("seed_vs_limit") > 0.8)
    # the printed scheme does not converge to the continuous model: its error stays
    assert r.errors["seed"][-1] > 5 * r.errors["corrected"][-1]
    assert r.errors["seed"][-1] > 0.9 * r.errors["seed"][0]
    d = r.to_dict()
    assert d["max_abs_difference_seed_minus_accurate_rad_s"] > 0
    assert "accurate" in r.table()


def test_accurate_refuses_clearance(drive):
    with pytest.raises(SimulationError, match="clearance"):
        accurate(replace(drive, cam=replace(drive.cam, clearance=1e-4)), 3.5, 0.1)
    run = discrete_scheme(replace(drive, cam=replace(drive.cam, clearance=1e-4)), 3.5, 0.2, 1e-3)
    assert np.all(np.isfinite(run.omega))


def test_dispatch(drive):
    scene = load_scene(SCENES / "cam_follower.toml")
    assert handles(scene, "constant_speed") and handles(scene, scene.study("constant_voltage"))
    assert not handles(load_scene(), "anything")
    r = run_study(scene, "constant_speed")
    assert r.to_dict()["inertia_max_kg_m2"] == pytest.approx(2.004e-3, rel=1e-3)
    assert len(r.to_dict()["cases"]) == 2
