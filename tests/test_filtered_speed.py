"""What a filtered speed estimate buys the speed loop (the design's note): the constant-gain
Kalman filter's response and phase against the difference over one sample, checked against
filterpy's own filter and the difference run sample by sample on a sine."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_toolkit.loop.actuator_bounds import filtered_speed
from servo_toolkit.loop.encoder_estimators import (BackwardDifference, KalmanEstimator, default_jerk,
                                                   speed_response, steady_state_gain)

TS, LSB = 2e-4, 2 * math.pi / 2048


def _phasor(t, y, f):
    """Complex amplitude of the sine at f in y(t) (least squares on cos, sin, offset)."""
    w = 2 * math.pi * f
    A = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)])
    c, s, _ = np.linalg.lstsq(A, y, rcond=None)[0]
    return complex(c, -s)


@pytest.mark.parametrize("f, jerk", [(20.0, 1e5), (80.0, 1e7), (150.0, 3e6)])
def test_the_filters_speed_response_is_filterpys_on_a_sine(f, jerk):
    n = int(round(40 / (f * TS)))
    t = np.arange(n) * TS
    amp = 0.5
    angle = amp * np.sin(2 * math.pi * f * t)
    speed = amp * 2 * math.pi * f * np.cos(2 * math.pi * f * t)
    kf, bd = KalmanEstimator(TS, LSB, jerk), BackwardDifference(TS, LSB)
    est, dif = np.empty(n), np.empty(n)
    for k in range(n):
        est[k] = kf.step(angle[k] / LSB)[1]  # an unquantized count: the filter's linear response
        dif[k] = bd.step(angle[k] / LSB)[1]
    keep = slice(n // 2, n)
    truth = _phasor(t[keep], speed[keep], f)
    F, _, K = steady_state_gain(TS, LSB, jerk)
    assert _phasor(t[keep], est[keep], f) / truth == pytest.approx(speed_response(F, K, TS, f)[0], rel=2e-3)
    # the difference lags half a sample exactly
    lag = -np.angle(_phasor(t[keep], dif[keep], f) / truth)
    assert lag == pytest.approx(math.pi * f * TS, rel=1e-3)


def test_the_extra_lag_is_the_filter_against_the_difference():
    from servo_toolkit import load_scene

    from .conftest import SCENES
    scene = load_scene(SCENES / "ema_reference.toml")
    kv, counts = 0.05, 2048
    fs = filtered_speed(scene, kv, counts, TS, scene.drivetrain.mid_stroke)
    jm = float(scene.drivetrain.motor_inertia([scene.drivetrain.mid_stroke])[0])
    m = scene.motor
    assert fs.crossover_hz == pytest.approx(kv * m.torque_constant / jm / (2 * math.pi))
    jerk = default_jerk(m.torque_constant, m.current_limit, jm, kv, TS)
    F, _, K = steady_state_gain(TS, 2 * math.pi / counts, jerk)
    kalman = np.angle(speed_response(F, K, TS, fs.crossover_hz)[0], deg=True)
    assert fs.extra_lag_deg == pytest.approx(-kalman - 180 * fs.crossover_hz * TS, abs=1e-9)  # lag: -phase
    assert filtered_speed(scene, kv, 0, TS, 0.0) is None


def test_the_design_says_what_a_filter_buys_where_the_encoder_caps_the_gain():
    """The gearmotor's 2048-count encoder caps its speed gain; the note weighs the filter at
    the gain the cap took away, and its ripple there is less than the difference's."""
    from servo_toolkit import load_scene
    from servo_toolkit.loop import design
    from servo_toolkit.loop.backlash_df import quantization_ripple

    from .conftest import ROOT
    scene = load_scene(ROOT / "tests" / "scenes" / "gearmotor_carriage.toml")
    b = design(scene).actuator
    assert b.capped_from is not None and b.filtered is not None
    assert quantization_ripple(b.capped_from, b.counts, b.sample_time) > b.allowance
    assert b.filtered.ripple < quantization_ripple(b.capped_from, b.counts, b.sample_time)
    text = "\n".join(b.notes())
    assert 'speed_estimator = "kalman"' in text and f"{b.filtered.ripple:.3g} A rms" in text
    assert b.to_dict()["filtered_speed"]["ripple_A_rms"] == b.filtered.ripple
