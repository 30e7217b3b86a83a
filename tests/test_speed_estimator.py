"""Speed estimators in the sampled closed loop: ideal speed, backward difference, Kalman filter.

The reference EMA samples at Ts = 0.1 ms with a 4096-count motor encoder: one count per
sample is a speed step of q/Ts = 15.3 rad/s, which the speed loop's direct gain (0.78 A per
rad/s) turns into about 12 A of current-reference steps.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from servo_toolkit import SceneError
from servo_toolkit.loop.encoder_estimators import KalmanEstimator, steady_state_covariance
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for, run
from servo_toolkit.sim import layout as lo
from servo_toolkit.loop.encoder_estimators import speed_noise_rms
from servo_toolkit.sim.kernel import measured_motor_angle, motor_angle

from .conftest import SCENES, build, variant

AMP, FREQ = math.radians(2.0), 8.0
SETTLE = 0.25  # s: two 8 Hz cycles after the start transient


@pytest.fixture(scope="module")
def ema_data():
    return tomllib.loads((SCENES / "ema_reference.toml").read_text())


@pytest.fixture(scope="module")
def controller(ema_data):
    return controller_for(build(ema_data))[0]


@pytest.fixture(scope="module")
def loops(ema_data, controller):
    """The 8 Hz 2 deg sine with each estimator; the scene variant asks for the Kalman filter,
    options override it."""
    scene = build(variant(ema_data, sensors__speed_estimator="kalman"))
    ref = Reference.sine(AMP, FREQ)
    out = {}
    for est in (None, "ideal", "difference"):
        model = build_model(scene, controller, ModelOptions(speed_estimator=est))
        out[model.speed_estimator] = (model, run(model, ref, 0.5, "rk4", output_dt=1e-4))
    return out


def _late(res):
    return res.times > SETTLE


def test_scene_choice_and_override(loops):
    assert set(loops) == {"kalman", "ideal", "difference"}
    kal = loops["kalman"][0]
    assert any("Kalman" in n for n in kal.notes)
    assert kal.state_names[-3:] == ("speed_estimator.angle_rad", "speed_estimator.speed_rad_s",
                                    "speed_estimator.acceleration_rad_s2")
    assert loops["ideal"][0].nx == kal.nx - 3


def test_kalman_loop_tracks_like_the_ideal_loop(loops):
    """Measured reason for the tolerance: the position loop sees the output through a 16-bit
    encoder (quantum 0.0055 deg); the Kalman loop stays within half an output count of the
    ideal-speed loop, the difference loop does not."""
    lsb = 2 * math.pi / 2**16
    ideal = loops["ideal"][1]
    late = _late(ideal)
    dev = {k: np.max(np.abs(loops[k][1].output_angle - ideal.output_angle)[late]) for k in ("kalman", "difference")}
    assert dev["kalman"] < 0.5 * lsb, dev["kalman"] / lsb
    assert dev["difference"] > 2 * dev["kalman"], dev
    # tracking error (q - reference) of the Kalman loop within 0.1 % of the ideal loop's
    e_i = np.max(np.abs(ideal.output_angle - ideal.reference_angle)[late])
    e_k = np.max(np.abs(loops["kalman"][1].output_angle - ideal.reference_angle)[late])
    assert abs(e_k - e_i) < 1e-3 * e_i


def test_current_reference_noise_follows_the_estimators_speed_noise(loops, controller):
    """Quantization noise in i_ref = the speed loop's direct gain x the estimate's noise:
    q/(sqrt(6) Ts) for the difference, (q/sqrt(12)) ||h|| for the filter (its speed impulse
    response). The measured ratio difference/Kalman (about 4.7) matches the predicted one."""
    kd = abs(controller.discrete_motion()[3][0, 2])
    ideal = loops["ideal"][1]
    late = _late(ideal)
    noise = {k: float(np.sqrt(np.mean((loops[k][1].current_reference - ideal.current_reference)[late] ** 2)))
             for k in ("difference", "kalman")}
    info = loops["kalman"][0].estimator
    q, ts = info["quantum_rad"], info["sample_time_s"]
    from servo_toolkit.loop.encoder_estimators import steady_state_gain
    f, _, k = steady_state_gain(ts, q, info["jerk_rad_s3"])
    predicted = {"difference": speed_noise_rms("difference", q, ts),
                 "kalman": speed_noise_rms("kalman", q, ts, f, k)}
    assert noise["difference"] == pytest.approx(kd * predicted["difference"], rel=0.1)
    assert noise["kalman"] == pytest.approx(kd * predicted["kalman"], rel=0.25)
    ratio = noise["difference"] / noise["kalman"]
    assert ratio > 3.0, ratio
    assert ratio == pytest.approx(predicted["difference"] / predicted["kalman"], rel=0.25)


def test_in_kernel_filter_equals_filterpy(loops):
    """The constant-gain filter run inside the kernel = filterpy's KalmanFilter started at the
    steady-state covariance, on the same count sequence (recorded at every sample)."""
    model, res = loops["kalman"]
    info = model.estimator
    q, ts, jerk = info["quantum_rad"], info["sample_time_s"], info["jerk_rad_s3"]
    P = model.P
    counts = [round(measured_motor_angle(P, model.T, p) / q) for p in res.trace("motor_side_angle_rad")]
    assert np.ptp(counts) > 100                     # the motor turns many counts
    est = KalmanEstimator(ts, q, jerk, position=counts[0] * q)
    est.filter.P = steady_state_covariance(ts, q, jerk)[1]
    offline = np.array([est.step(c) for c in counts])
    kernel = res.states[:, -3:]
    scale = np.max(np.abs(offline), axis=0)
    np.testing.assert_allclose(kernel, offline, rtol=0, atol=1e-9 * scale.max())
    assert np.max(np.abs(kernel[:, 1] - offline[:, 1])) < 1e-9 * scale[1]


@pytest.mark.parametrize("kind", ["difference", "kalman"])
def test_fine_encoder_approaches_the_true_speed(ema_data, controller, kind):
    """Difference: the mean speed over the last sample, error q/(sqrt(6) Ts) from quantization
    (shrinks 16x per 4 more bits). Kalman: error shrinks with the count to a small floor."""
    ref = Reference.sine(AMP, FREQ)
    errs = []
    for bits in (12, 16, 20, 28):
        scene = build(variant(ema_data, sensors__motor_encoder_counts=2**bits))
        model = build_model(scene, controller, ModelOptions(speed_estimator=kind))
        res = run(model, ref, 0.2, "rk4", output_dt=1e-4)
        late = res.times > 0.05
        w = res.motor_speed
        est = res.trace("speed_estimator.speed_rad_s")
        truth = np.r_[w[0], 0.5 * (w[1:] + w[:-1])] if kind == "difference" else w
        errs.append(float(np.sqrt(np.mean((est - truth)[late] ** 2))))
        if kind == "difference" and bits <= 20:
            assert errs[-1] == pytest.approx(speed_noise_rms(kind, 2 * math.pi / 2**bits, 1e-4), rel=0.1)
    amp = np.max(np.abs(w))
    assert all(a > b for a, b in zip(errs, errs[1:])), errs
    assert errs[-1] < 1e-4 * amp, (errs, amp)


def test_reference_solver_drives_the_same_estimator(ema_data, controller):
    """solve_ivp restarts at every sample with the same compiled update: agreement with RK4
    (unquantized encoder, so rounding cannot amplify solver differences)."""
    scene = build(variant(ema_data, sensors__speed_estimator="difference"))
    model = build_model(scene, controller, ModelOptions(quantization=False))
    ref = Reference.sine(AMP, FREQ)
    a = run(model, ref, 0.01, "rk4", 2e-5, output_dt=1e-4)
    b = run(model, ref, 0.01, "reference", output_dt=1e-4)
    assert np.max(np.abs(a.output_angle - b.output_angle)) < 1e-7 * AMP
    # records hold the state after each sample; the reference's last record precedes the
    # sample at t_final (the RK4 loop samples there), so it is left out
    sa, sb = a.trace("speed_estimator.speed_rad_s")[:-1], b.trace("speed_estimator.speed_rad_s")[:-1]
    assert np.max(np.abs(sa - sb)) < 1e-6 * np.max(np.abs(sb))


def test_motor_angle_table_integrates_the_ratio(ema_data, controller):
    """The motor-angle row's slope is N(p): a centred difference of the table equals N."""
    model = build_model(build(ema_data), controller)
    from servo_toolkit.sim.kernel import hermite
    for p in np.linspace(model.stroke[0], model.stroke[1], 7):
        h = 1e-6
        slope = (motor_angle(model.P, model.T, p + h) - motor_angle(model.P, model.T, p - h)) / (2 * h)
        assert slope == pytest.approx(hermite(model.T, lo.T_N, model.P, p)[0], rel=1e-7)
    assert motor_angle(model.P, model.T, model.q0) == pytest.approx(0.0, abs=1e-9)


def test_continuous_mode_and_bad_settings(ema_data, controller):
    scene = build(variant(ema_data, sensors__speed_estimator="kalman"))
    model = build_model(scene, controller, ModelOptions(controller_mode="continuous"))
    assert model.speed_estimator == "ideal"
    assert any("true motor speed" in n for n in model.notes)
    no_encoder = build(variant(ema_data, sensors__motor_encoder_counts=0))
    with pytest.raises(SceneError, match="motor_encoder_counts"):
        build_model(no_encoder, controller, ModelOptions(speed_estimator="kalman"))
    with pytest.raises(ValueError):
        ModelOptions(speed_estimator="tachometer")
    with pytest.raises(ValueError):
        ModelOptions(estimator_jerk=-1.0)


@settings(max_examples=200, deadline=None)
@given(dt=st.floats(1e-7, 1.0), var=st.floats(1e-12, 1e12))
def test_the_filters_process_noise_is_filterpys(dt, var):
    """The estimator's process noise is filterpy's ``Q_discrete_white_noise`` to the bit."""
    from filterpy.common import Q_discrete_white_noise
    from servo_toolkit.loop.encoder_estimators import white_noise_q
    assert np.array_equal(white_noise_q(dt, var), Q_discrete_white_noise(dim=3, dt=dt, var=var))
