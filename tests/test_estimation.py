"""Speed and acceleration from quantized encoder counts: Kalman filter vs backward differences."""

import math

import numpy as np
import pytest

from servo_toolkit.loop.encoder_estimators import (BackwardDifference, KalmanEstimator, backward_difference_estimate,
                                      compare_estimators, encoder_quantum, kalman_estimate, quantize,
                                      steady_state_gain)

T = 1e-4
A, W = math.radians(2.0), 2 * math.pi * 8.0     # the 8 Hz, 2 deg small-signal motion


def _sine(duration=0.4):
    t = np.arange(0.0, duration, T)
    return t, A * np.sin(W * t), A * W * np.cos(W * t), -A * W**2 * np.sin(W * t)


@pytest.fixture(scope="module")
def comparisons():
    t, q, v, a = _sine()
    return {bits: compare_estimators(t, q, v, a, encoder_quantum(2**bits)) for bits in (12, 16, 20)}


def test_kalman_beats_backward_differences_on_a_quantized_sine(comparisons):
    c = comparisons[16]
    assert c.rms["kalman"]["speed"] < 0.2 * c.rms["backward"]["speed"]
    assert c.rms["kalman"]["acceleration"] < 0.01 * c.rms["backward"]["acceleration"]
    # position: both are within the quantization error (q / sqrt(12)) of the truth
    assert c.rms["kalman"]["position"] < 1.5 * c.quantum / math.sqrt(12)
    d = c.to_dict()
    assert d["kalman"]["rms_speed_error_rad_s"] == c.rms["kalman"]["speed"]


def test_errors_shrink_as_resolution_grows(comparisons):
    for name in ("kalman", "backward"):
        for key in ("speed", "acceleration"):
            e = [comparisons[b].rms[name][key] for b in (12, 16, 20)]
            assert e[0] > e[1] > e[2], (name, key, e)


def test_backward_difference_speed_lags_half_a_sample():
    """v_k = (z_k - z_{k-1})/T is the exact speed at t_k - T/2 (to O(T^2)): the measured lag
    must come out as T/2 with a fine encoder."""
    t, q, v, a = _sine(0.2)
    c = compare_estimators(t, q, v, a, encoder_quantum(2**26))
    assert c.lag["backward"]["speed"] == pytest.approx(T / 2, rel=0.05)


def test_per_sample_step_equals_the_batch():
    t, q, _, _ = _sine(0.05)
    quantum = encoder_quantum(2**14)
    counts = quantize(q, quantum)
    batch = kalman_estimate(counts, T, quantum, jerk=3000.0)
    est = KalmanEstimator(T, quantum, jerk=3000.0, position=counts[0] * quantum)
    steps = np.array([est.step(c) for c in counts])
    np.testing.assert_allclose(steps, np.c_[batch.position, batch.speed, batch.acceleration], rtol=1e-10, atol=1e-12)
    bd = backward_difference_estimate(counts, T, quantum)
    b = BackwardDifference(T, quantum)
    np.testing.assert_allclose(np.array([b.step(c) for c in counts]), np.c_[bd.position, bd.speed, bd.acceleration],
                               rtol=1e-12, atol=1e-12)


def test_steady_state_gain_is_the_converged_filter_gain():
    quantum = encoder_quantum(2**16)
    f, h, k = steady_state_gain(T, quantum, 3000.0)
    est = KalmanEstimator(T, quantum, 3000.0)
    for _ in range(4000):
        est.step(0)
    np.testing.assert_allclose(est.filter.K.ravel(), k, rtol=1e-6)
    assert np.all(np.abs(np.linalg.eigvals(f - np.outer(k, h[0]) @ f)) < 1)   # stable estimator


def test_bad_parameters_raise():
    with pytest.raises(ValueError):
        KalmanEstimator(T, 0.0, 1.0)
    with pytest.raises(ValueError):
        quantize([0.1], -1.0)
    with pytest.raises(ValueError, match="uniform"):
        compare_estimators([0, 1, 3], [0, 0, 0], [0, 0, 0], [0, 0, 0], 1e-3)
