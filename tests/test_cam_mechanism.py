"""Cam drive of seed 002: law, inertia, load torque, clearance, both solvers."""

import json
import math
import tomllib
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import brentq

from servo_toolkit import SceneError, SimulationError, load_scene
from servo_toolkit.cli import main as cli_main
from servo_toolkit.components.cam.geometry import modified_constant_velocity
from servo_toolkit.studies.mechanisms.dispatch import handles
from servo_toolkit.studies.run import run_study
from servo_toolkit.components.cam import kernels as cam_kernels
from servo_toolkit.components.cam.drive import CamDrive, clearance_hysteresis
from servo_toolkit.studies.cam.constant_speed import constant_speed
from servo_toolkit.loop.encoder_estimators import kalman_estimate, quantize
from servo_toolkit.studies.cam.estimation import (compare_on_reference, rms_jerk, steady_state_noise,
                                                     true_acceleration)
from servo_toolkit.studies.cam.voltage import accurate, constant_voltage, discrete_scheme

from .conftest import SCENES, build, variant

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


def _seed_law(theta, a):
    """Seed 002 cam law (REFERENCE.md) written out again: s and ds/dtheta, d2s/dtheta2."""
    q = math.pi / 4
    s4, c4 = math.sin(4 * theta), math.cos(4 * theta)
    if theta < q:
        return a * (theta - s4 / 4), a * (1 - c4), 4 * a * s4
    if theta < 3 * q:
        return 2 * a * theta - math.pi * a / 4, 2 * a, 0.0
    if theta < 4 * q:
        return math.pi * a / 2 + a * (theta - s4 / 4), a * (1 - c4), 4 * a * s4
    if theta < 5 * q:
        return 2.5 * math.pi * a - a * (theta - s4 / 4), -a * (1 - c4), -4 * a * s4
    if theta < 7 * q:
        return 3.75 * math.pi * a - 2 * a * theta, -2 * a, 0.0
    return 2 * math.pi * a - a * (theta - s4 / 4), -a * (1 - c4), -4 * a * s4


@pytest.mark.parametrize("tilt_deg, heading_deg, mu", [(60.0, 120.0, 0.2), (0.0, 0.0, 0.001)])
def test_load_torque_closed_form_at_several_angles(drive, tilt_deg, heading_deg, mu):
    """M = M_f + (m a - G sin(gamma) cos(beta) + sign(v) f) ds/dtheta (seed 002 eq 3) with f of
    eq 1 with the corrected denominator, f = mu ((m a - G_x) tan(alpha) + G_y + |G_z|) /
    (1 - sign(v) mu tan(alpha)) (tan(alpha) = s' / (r0 + s), signed), evaluated here from the
    printed law, at angles on both strokes where the cam force and the side reaction are
    positive (the cases the printed equation covers)."""
    r0, w = 0.09, 1.0
    cam = replace(drive.cam, guide_friction_coefficient=mu, base_radius=r0)
    d = replace(drive, cam=cam)
    gamma, beta = math.radians(tilt_deg), math.radians(heading_deg)
    r = constant_speed(d, w, 1e-3, [gamma], [beta])
    m, g = cam.follower_mass, cam.follower_weight
    gx, gy, gz = g * math.sin(gamma) * math.cos(beta), g * math.sin(gamma) * math.sin(beta), g * math.cos(gamma)
    angles = [0.3, 0.6, 1.2, 2.0, 2.6, 2.9, 3.4, 4.5] if tilt_deg else [0.3, 0.6, 1.2, 2.0]
    for th in angles:
        k = int(round(th / 1e-3))
        theta = r.theta[k]
        s, ds, d2s = _seed_law(theta, A)
        v, a = ds * w, d2s * w * w
        sigma = math.copysign(1.0, v)
        tan_a = ds / (r0 + s)
        f = mu * ((m * a - gx) * tan_a + gy + abs(gz)) / (1 - sigma * mu * tan_a)
        p = m * a - gx + sigma * f
        assert p > 0 and p * tan_a + gy > 0, th  # the printed equation's case
        expected = drive.shaft_friction + p * ds
        assert r.torque[0, k] == pytest.approx(expected, rel=1e-10, abs=1e-13), th
        assert r.gravity[0, k] == pytest.approx(-gx * ds, rel=1e-12, abs=1e-15), th
        assert r.friction[0, k] == pytest.approx(sigma * f * ds, rel=1e-10, abs=1e-15), th


def test_constant_speed_with_clearance_lags_by_c_after_reversal(drive):
    """Eqs 6-8 at constant speed: after engaging, the follower trails the law by c on the
    rise; at the top (theta = pi) it stays put while the cam takes up the play 2c, which
    near the top (s_max - s = A (d - sin(4 d) / 4) ~ 8 A d^3 / 3, d = theta - pi) lasts
    A (d - sin(4 d) / 4) = 2 c;
    then it trails by c on the return (s_o = s + c). While it stays put (flat) the shaft
    only carries M_f."""
    c, step = 5e-4, 1e-4
    d = replace(drive, cam=replace(drive.cam, clearance=c))
    r = constant_speed(d, 1.0, step, [0.0])
    s = np.array([_seed_law(th, A)[0] for th in r.theta])
    lag = r.travel - s
    rise = (r.theta > 0.5) & (r.theta < math.pi - 0.01)
    fall = (r.theta > math.pi + 0.3) & (r.theta < 2 * math.pi - 0.5)
    assert np.allclose(lag[rise], -c, atol=1e-12) and np.allclose(lag[fall], c, atol=1e-12)
    top = (r.theta >= math.pi) & (r.theta <= math.pi + 0.25)
    held = top & (np.abs(r.travel - 1.5 * math.pi * A + c) < 1e-12)
    dwell = brentq(lambda x: A * (x - math.sin(4 * x) / 4) - 2 * c, 1e-6, math.pi / 4)
    assert dwell == pytest.approx((3 * c / (4 * A)) ** (1 / 3), rel=0.02)
    assert r.theta[held].max() - math.pi == pytest.approx(dwell, abs=2 * step)
    inner = held & (r.theta > math.pi + 2 * step)
    assert np.allclose(r.torque[0, inner], drive.shaft_friction, rtol=0, atol=1e-15)
    assert r.to_dict()["clearance_m"] == c and "clearance" in r.table()
    # without clearance the travel is the law itself
    assert np.allclose(constant_speed(drive, 1.0, step, [0.0]).travel, s, atol=1e-15)


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


@pytest.mark.parametrize("tilt_deg, mu", [(0.0, 0.001), (170.0, 0.3), (60.0, 0.2)])
def test_shaft_acceleration_balances_the_follower_load(drive, tilt_deg, mu):
    """cam_kernels.shaft_acceleration (the follower's weight and guide friction for another
    model's kernel): with its w', J_m w' + M_l(theta, v, a) = torque, M_l = P s' from the
    vectorized CamDrive.follower_force (eqs 1, 3); the inertial part m a s' splits into
    m s'^2 w' (in J) and m s' s'' w^2 (the velocity term)."""
    d = replace(drive, cam=replace(drive.cam, gravity_tilt=math.radians(tilt_deg), gravity_heading=0.3,
                                   guide_friction_coefficient=mu))
    p = cam_kernels.pack_cam(d.cam)
    m = d.cam.follower_mass
    for th, w, torque in [(0.3, 4.0, 0.2), (1.2, 9.0, -0.05), (3.4, 6.0, 0.1), (5.9, -3.0, 0.3)]:
        jet = d.law(th)
        s1, s2 = float(jet.d1), float(jet.d2)
        j = d.rotor_inertia + m * s1 * s1
        dw, m_g = cam_kernels.shaft_acceleration(p, th, w, torque, j, m * s1 * s2 * w * w, 0.0)
        a = s2 * w * w + s1 * dw
        force, f = d.follower_force(th, s1 * w, a)
        assert d.rotor_inertia * dw + float(force) * s1 == pytest.approx(torque, rel=1e-10, abs=1e-12)
        gx = d.gravity()[0]
        assert m_g == pytest.approx((np.sign(s1 * w) * float(f) - gx) * s1, rel=1e-10, abs=1e-14)
        # smoothed direction: tanh(w / w_s) -> sign(w) for w >> w_s
        dws, _ = cam_kernels.shaft_acceleration(p, th, w, torque, j, m * s1 * s2 * w * w, 1e3)
        assert dws == pytest.approx(dw, rel=1e-12)
    # tilt and guide friction change the shaft load (what the closed-loop model leaves out)
    flat = cam_kernels.pack_cam(drive.cam)
    j = drive.rotor_inertia + m * float(drive.law(1.2).d1) ** 2
    assert (cam_kernels.shaft_acceleration(p, 1.2, 5.0, 0.1, j, 0.0, 0.0)[0]
            != cam_kernels.shaft_acceleration(flat, 1.2, 5.0, 0.1, j, 0.0, 0.0)[0]) or tilt_deg == 0.0


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


def test_convergence_ladder_records_failed_steps(drive):
    """At T = 10 ms the ladder starts at 40 ms, where the explicit corrected scheme reverses
    the cam; the study records the failures per step and goes on."""
    r = constant_voltage(drive, 3.5, 0.5, 0.01, refinements=1)
    expected = set()
    for h in r.steps:  # which runs stop, found independently
        for name in ("seed", "corrected"):
            try:
                discrete_scheme(drive, 3.5, 0.5, h, name)
            except SimulationError:
                expected.add((float(h), name))
    assert expected and {(h, name) for h, name, _ in r.ladder_failures} == expected
    for h, name, why in r.ladder_failures:
        assert "reversed" in why and f"T = {h:.4g} s" in why
    for i, h in enumerate(r.steps):
        for key, name in (("seed", "seed"), ("corrected", "corrected"), ("seed_vs_limit", "seed")):
            assert math.isnan(r.errors[key][i]) == ((float(h), name) in expected)
    d = r.to_dict()
    json.dumps(d, allow_nan=False)
    assert any(c["failures"] for c in d["convergence"])
    assert "failed" in r.table() and "stopped" in r.table()
    # the study step itself stopping is an error naming the scheme and the step
    with pytest.raises(SimulationError, match=r"T = 0.05 s"):
        constant_voltage(drive, 3.5, 0.5, 0.05)


def test_clearance_runs_discrete_schemes_and_skips_accurate(drive):
    """With clearance c the follower stays put until the cam law has travelled c (eqs 6-8):
    up to there the drive runs exactly as with the follower removed (flat: no gravity along
    the guide, v = 0 so no friction), whereas the rigid cam loads it from the start."""
    c = 1e-4
    loose = replace(drive, cam=replace(drive.cam, clearance=c))
    r = constant_voltage(loose, 3.5, 0.3, 1e-3)
    assert r.reference is None and r.seed_limit is None and r.estimation is None and r.steps.size == 0
    assert "clearance" in r.skipped and "skipped" in r.table()
    d = r.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["accurate_comparison"].startswith("skipped") and d["clearance_m"] == c
    assert "omega_accurate_rad_s" not in d
    bare = discrete_scheme(drive.without_follower(), 3.5, 0.3, 1e-3, "seed")
    rigid = discrete_scheme(drive, 3.5, 0.3, 1e-3, "seed")
    theta_c = (3 * c / (8 * A)) ** (1 / 3)  # A (theta - sin(4 theta)/4) = 8 A theta^3 / 3 = c
    free = r.seed.theta < 0.95 * theta_c
    assert free.sum() > 5
    assert np.array_equal(r.seed.omega[free], bare.omega[free])
    assert np.abs(rigid.omega[free] - bare.omega[free]).max() > 0
    assert np.abs(r.seed.omega - bare.omega).max() > 0.1  # engaged later
    with pytest.raises(SimulationError, match="clearance"):
        constant_voltage(loose, 3.5, 0.3, 1e-3, speed_estimator="kalman")


def test_cli_clearance_and_simulation_errors(tmp_path, capsys):
    text = (SCENES / "cam_follower.toml").read_text()
    loose = tmp_path / "loose.toml"
    loose.write_text(text.replace('clearance = "0 mm"', 'clearance = "0.1 mm"').replace('"3 s"', '"0.3 s"'))
    assert cli_main(["simulate", str(loose), "--study", "constant_voltage", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["accurate_comparison"].startswith("skipped")
    # a step too large for the explicit scheme: one line on stderr, exit 2 (not 1, which
    # means "requirements not met"), no traceback
    assert cli_main(["simulate", str(SCENES / "cam_follower.toml"), "--study", "constant_voltage",
                     "--dt", "0.05"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and "T = 0.05 s" in err


def test_dispatch(drive):
    scene = load_scene(SCENES / "cam_follower.toml")
    assert handles(scene, "constant_speed") and handles(scene, scene.study("constant_voltage"))
    assert not handles(load_scene(), "anything")
    r = run_study(scene, "constant_speed")
    assert r.to_dict()["inertia_max_kg_m2"] == pytest.approx(2.004e-3, rel=1e-3)
    assert len(r.to_dict()["cases"]) == 2


# --- speed and acceleration estimates: backward differences or a Kalman filter on the counts ---

T_EST, COUNTS = 1e-3, 4096
Q = 2 * math.pi / COUNTS


@pytest.fixture(scope="module")
def reference_1s(drive):
    return accurate(drive, 3.5, 1.0, t_eval=np.arange(1001) * T_EST)


@pytest.fixture(scope="module")
def estimation(drive, reference_1s):
    return compare_on_reference(drive, 3.5, reference_1s, COUNTS)


def test_difference_error_is_quantization_noise_plus_lag(estimation):
    """Backward differences of counts: independent uniform errors of variance q^2/12 give
    speed noise q/(T sqrt 6) and acceleration noise q/(T^2 sqrt 2); the lags T/2 and T add
    (T/2) rms(w') and T rms(w'') in quadrature."""
    pr = estimation.predicted
    assert pr["difference_speed_noise"] == pytest.approx(Q / (T_EST * math.sqrt(6)))
    assert pr["difference_acceleration_noise"] == pytest.approx(Q / (T_EST**2 * math.sqrt(2)))
    for key in ("speed", "acceleration"):
        expected = math.hypot(pr[f"difference_{key}_noise"], pr[f"difference_{key}_lag"])
        assert estimation.rms("difference", key) == pytest.approx(expected, rel=0.06), key
    assert estimation.comparison.lag["backward"]["speed"] == pytest.approx(T_EST / 2, rel=0.05)


def test_steady_state_noise_matches_monte_carlo():
    """The Lyapunov solution of the fixed-gain filter against filterpy on white uniform noise."""
    jerk = 7e4
    noise = steady_state_noise(T_EST, Q, jerk)
    z = np.random.default_rng(1).uniform(-0.5, 0.5, 12000)   # counts' rounding error
    est = kalman_estimate(z, T_EST, Q, jerk)
    measured = [np.std(x[2000:]) for x in (est.position, est.speed, est.acceleration)]
    assert np.allclose(measured, noise, rtol=0.04)
    assert noise[0] < Q / math.sqrt(12) and noise[1] < Q / (T_EST * math.sqrt(6))


def test_kalman_beats_differences_by_the_predicted_factor(estimation):
    """At 4096 counts/rev and T = 1 ms on the 3.5 V run (first second) the difference's speed
    error is noise 0.63 (+) lag 0.15 = 0.64 rad/s; the filter's is its steady-state noise
    0.19 (+) its model bias 0.33 = 0.38 rad/s: a predicted factor 1.7 (acceleration 5)."""
    for key, floor in (("speed", 1.5), ("acceleration", 4.0)):
        predicted = estimation.expected("difference", key) / estimation.expected("kalman", key)
        assert estimation.ratio(key) == pytest.approx(predicted, rel=0.06), key
        assert estimation.ratio(key) > floor, key
        assert estimation.rms("kalman", key) == pytest.approx(estimation.expected("kalman", key), rel=0.06)
    d = estimation.to_dict()
    assert d["kalman"]["rms_speed_error_rad_s"] < d["difference"]["rms_speed_error_rad_s"]
    assert d["error_ratio_difference_to_kalman"]["speed"] == pytest.approx(estimation.ratio("speed"))
    assert "Kalman" in estimation.table()


def test_kalman_in_scheme_equals_filterpy_offline(drive, estimation):
    jerk = estimation.comparison.jerk
    run = discrete_scheme(drive, 3.5, 0.5, T_EST, "corrected", "kalman", COUNTS, jerk)
    assert np.array_equal(run.counts, quantize(run.theta, Q))
    offline = kalman_estimate(run.counts, T_EST, Q, jerk)     # filterpy batch_filter
    for key in ("position", "speed", "acceleration"):
        assert np.allclose(getattr(run.estimate, key), getattr(offline, key), rtol=1e-12, atol=1e-12), key
    # the estimates steer the scheme: a different jerk level gives a different run
    other = discrete_scheme(drive, 3.5, 0.5, T_EST, "corrected", "kalman", COUNTS, jerk / 10)
    assert np.abs(other.omega - run.omega).max() > 1e-3


def test_kalman_scheme_physics(drive, reference_1s):
    bare = drive.without_follower()
    for scheme in ("seed", "corrected"):
        run = discrete_scheme(bare, 3.5, 0.6, T_EST, scheme, "kalman", COUNTS, 1e4)
        assert run.omega[-1] == pytest.approx(13.36, abs=0.005)
    # a fine encoder: the filter removes the differences' lag, which is what keeps the
    # corrected scheme off the continuous model at T = 1 ms
    jerk = rms_jerk(true_acceleration(drive, 3.5, reference_1s.theta, reference_1s.omega), T_EST, 100)
    kal = discrete_scheme(drive, 3.5, 1.0, T_EST, "corrected", "kalman", 2**20, jerk)
    dif = discrete_scheme(drive, 3.5, 1.0, T_EST, "corrected")
    rms = lambda run: float(np.sqrt(np.mean((run.omega - reference_1s.omega) ** 2)))
    assert rms(kal) < 0.05 * rms(dif) and rms(kal) < 0.05
    # the printed scheme feeds m a s' back explicitly (gain m s'^2 / J = 0.978): through
    # the fine encoder's filter that loop grows a period-2 oscillation, reported as such
    with pytest.raises(SimulationError, match="period-2"):
        discrete_scheme(drive, 3.5, 1.0, T_EST, "seed", "kalman", 2**20, jerk)
    with pytest.raises(SimulationError, match="clearance"):
        discrete_scheme(replace(drive, cam=replace(drive.cam, clearance=1e-4)), 3.5, 0.1, T_EST, "seed",
                        "kalman", COUNTS, jerk)
    with pytest.raises(ValueError, match="speed_estimator"):
        discrete_scheme(drive, 3.5, 0.1, T_EST, "seed", "median")


def test_default_path_reproduces_published_numbers():
    """The scene's 3.5 V study with the default (seed's differences) gives the numbers of the
    committed scheme (README / notebook 04), unchanged by the estimator option."""
    scene = load_scene(SCENES / "cam_follower.toml")
    r = run_study(scene, "constant_voltage")
    d = r.to_dict()
    assert d["speed_estimator"] == "difference" and r.kalman is None
    assert d["mean_speed_accurate_rad_s"] == pytest.approx(8.4982, abs=5e-5)
    assert d["mean_speed_seed_rad_s"] == pytest.approx(6.7811, abs=5e-5)
    assert d["mean_speed_corrected_rad_s"] == pytest.approx(5.4558, abs=5e-5)
    assert d["max_abs_difference_seed_minus_accurate_rad_s"] == pytest.approx(39.28, abs=5e-3)
    assert [c["startup_max_abs_error_seed_rad_s"] for c in d["convergence"]] == pytest.approx(
        [0.7157, 0.7893, 0.8267, 0.8456], abs=5e-5)
    assert d["estimation"]["encoder_counts_per_rev"] == 4096


def test_study_keys_select_the_estimator():
    data = tomllib.loads((SCENES / "cam_follower.toml").read_text())
    base = {"studies__constant_voltage__duration": "0.3 s"}
    r = run_study(build(variant(data, **base, studies__constant_voltage__speed_estimator="kalman",
                                studies__constant_voltage__encoder_counts=1024)), "constant_voltage")
    d = r.to_dict()
    assert d["speed_estimator"] == "kalman" and set(r.kalman) == {"seed", "corrected"}
    assert d["estimation"]["encoder_counts_per_rev"] == 1024
    assert len(d["omega_corrected_kalman_rad_s"]) == len(d["t_s"])
    assert "Kalman estimates" in r.table()
    sensors = build(variant(data, **base, sensors={"motor_encoder_counts": 2000}))
    assert run_study(sensors, "constant_voltage").to_dict()["estimation"]["encoder_counts_per_rev"] == 2000
    for key, bad in (("speed_estimator", "median"), ("encoder_counts", 0), ("encoder_counts", 10.5),
                     ("kalman_jerk", "-3 rad/s^3")):
        with pytest.raises(SceneError, match=f"studies.constant_voltage.{key}"):
            run_study(build(variant(data, **base, **{f"studies__constant_voltage__{key}": bad})),
                      "constant_voltage")


def test_clearance_keeps_each_scheme_on_its_own(drive):
    """With 0.5 mm clearance the corrected scheme reverses the cam at the study step; the
    seed's scheme still runs through and gives its known speed (5.33 to 5.54 rad/s to two
    decimals over the last turns), and the study says that speed is ill-conditioned."""
    d = replace(drive, cam=replace(drive.cam, clearance=0.5e-3))
    r = constant_voltage(d, 3.5, 3.0, 1e-3)
    with pytest.raises(SimulationError, match="reversed"):  # found independently
        discrete_scheme(d, 3.5, 3.0, 1e-3, "corrected")
    assert set(r.scheme_failures) == {"corrected"} and "reversed" in r.scheme_failures["corrected"]
    assert r.corrected.t[-1] < 3.0 and r.seed.t[-1] == pytest.approx(3.0)
    assert 5.325 <= r.mean_speed(r.seed) <= 5.545
    c = r.conditioning["seed"]
    assert c["ill_conditioned"] and c["condition_number"] > 1e6
    # the probe is what it says: the same scheme at a voltage 1e-12 higher moves that much
    moved = discrete_scheme(d, 3.5 * (1 + 1e-12), 3.0, 1e-3, "seed")
    assert np.max(np.abs(moved.omega - r.seed.omega)) <= c["max_speed_change_rad_s"]
    out = r.to_dict()
    json.dumps(out, allow_nan=False)
    assert out["scheme_failures"] == r.scheme_failures and out["conditioning"]["seed"]["ill_conditioned"]
    assert "ILL-CONDITIONED" in r.table() and "corrected scheme stopped" in r.table()


def test_small_clearance_is_well_conditioned(drive):
    d = replace(drive, cam=replace(drive.cam, clearance=0.05e-3))
    r = constant_voltage(d, 3.5, 3.0, 1e-3)
    assert not r.scheme_failures
    assert {k: c["ill_conditioned"] for k, c in r.conditioning.items()} == {"seed": False, "corrected": False}
    assert "ILL-CONDITIONED" not in r.table()


def test_clearance_study_from_the_command_line(tmp_path, capsys):
    text = (SCENES / "cam_follower.toml").read_text().replace('clearance = "0 mm"', 'clearance = "0.5 mm"')
    assert 'clearance = "0.5 mm"' in text
    path = tmp_path / "cam.toml"
    path.write_text(text)
    assert cli_main(["simulate", str(path), "--study", "constant_voltage", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert 5.325 <= d["mean_speed_seed_rad_s"] <= 5.545 and "corrected" in d["scheme_failures"]


def _angles(rng, n):
    """Every segment boundary of the law over +-4 turns, an ulp either side of each, n random
    angles and the edge values."""
    b = np.arange(-16, 17) * (math.pi / 4)
    near = np.concatenate([np.nextafter(b, np.inf), np.nextafter(b, -np.inf)])
    return np.concatenate([b, near, rng.uniform(-30, 30, n), [0.0, -0.0, 2 * math.pi, -2 * math.pi, 1e-300]])


@pytest.mark.parametrize("a", [0.035, 1.0, 0.0, -0.2, 3.7])
def test_compiled_law_is_the_vectorized_law_at_every_segment_edge(a):
    """The compiled law (cam.h) at the segments' edges, an ulp either side, negative angles and
    several turns: the vectorized law's s within 2 ulp of its largest term 4 pi |A| (the kernels
    may fuse a product into a sum), s' and s'' within an ulp of their scales 2 |A| and 4 |A|."""
    th = _angles(np.random.default_rng(1), 400)
    jet = modified_constant_velocity(th, a)
    got = np.array([cam_kernels.law(float(t), a) for t in th])
    for k, (want, scale) in enumerate(((jet.value, 2 * math.ulp(4 * math.pi * abs(a))),
                                       (jet.d1, math.ulp(2 * abs(a))), (jet.d2, math.ulp(4 * abs(a))))):
        assert np.max(np.abs(got[:, k] - want)) <= scale, k


def test_compiled_friction_is_the_vectorized_follower_force(drive):
    """The compiled guide friction's fixed point (seed 002 eq 1) equals the vectorized
    CamDrive.follower_force's, over drives with other friction coefficients, follower masses,
    gravity directions and base radii, at random angles, speeds and accelerations."""
    rng = np.random.default_rng(2)
    for _ in range(30):
        cam = replace(drive.cam, guide_friction_coefficient=float(rng.choice([0.0, rng.uniform(0.0, 0.6)])),
                      follower_mass=drive.cam.follower_mass * rng.uniform(0.1, 5.0),
                      gravity_tilt=rng.uniform(0.0, math.pi), gravity_heading=rng.uniform(-math.pi, math.pi),
                      base_radius=drive.cam.pitch_base_radius * rng.uniform(0.8, 2.0))
        d = replace(drive, cam=cam)
        p = cam_kernels.pack(d)
        for _ in range(40):
            th, v, acc = rng.uniform(-10, 10), rng.normal(0.0, 0.3), rng.normal(0.0, 20.0)
            jet = d.law(th)
            force, f = d.follower_force(th, v, acc)
            kf, kfr = cam_kernels.friction(p, float(jet.value), float(jet.d1), float(np.sign(v)),
                                           cam.follower_mass * acc - p[3], 0.0)
            assert kf == pytest.approx(float(force), rel=1e-12, abs=1e-12 * abs(float(f)))
            assert kfr == pytest.approx(float(f), rel=1e-12, abs=1e-15)


def test_discrete_scheme_reports_each_outcome(drive):
    """The compiled discrete scheme's status: 0 a run to the end, 2 a reversed shaft, 1 a
    non-finite speed (no rotor inertia: a division by zero in IEEE arithmetic; a vanishing
    resistance: an infinite current)."""
    p = cam_kernels.pack(drive)
    theta, omega, status = cam_kernels.discrete(p, 3.5, 200, 1e-3, True)
    assert status == 0 and theta.shape == omega.shape == (201,) and np.all(np.isfinite(omega))
    assert cam_kernels.discrete(p, -3.5, 200, 1e-3, True)[2] == 2
    q = p.copy()
    q[8] = 0.0  # J_m
    assert cam_kernels.discrete(q, 3.5, 10, 1e-3, True)[2] == 1
    q = p.copy()
    q[10] = 1e-300  # R
    assert cam_kernels.discrete(q, 3.5, 10, 1e-3, True)[2] == 1
