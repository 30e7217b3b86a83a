"""Features of time traces that the data show by themselves: where a search starts.

As the inertia line and the modes of a frequency response (:mod:`.features`), a few numbers
read off a trace by linear regression locate the parameters before any nonlinear fit:

voltage-driven traces (:func:`step_features`)
    The steady gain K (rad/s per V) and the time constant tau (s) of the motor speed's
    response to the voltage, ``tau w' + w = K u``, regressed on integrals (noise on the
    angle is not differentiated): ``int theta = K int int u - tau theta`` from rest.
closed-loop traces (:func:`loop_features`)
    The motor current regressed on the output's acceleration, speed, direction of motion
    and a constant (the inverse-dynamics model of a rigid drive, ``i = (M a + Fv v + Fc
    sign(v) + F0) / (N Kt)``): each term's share of the current, from Savitzky-Golay
    derivatives of the position.

The same function reads the model's traces and the data's; a search fits the model's
features to the data's (:func:`~.search.global_least_squares`), which needs no exact model:
the features only have to move with the parameters as the data's would.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import integrate, signal

#: mismatch given to a feature one trace shows and the other does not (nepers)
MISSING = 3.0
#: length of the Savitzky-Golay window (s) of the derivatives of a position
SMOOTHING_S = 0.01


def step_features(time_s, voltage, motor_angle) -> tuple:
    """Steady gain (rad/s per V) and time constant (s) of motor speed / voltage.

    Returns
    -------
    tuple
        ``(gain, tau)``; None for a value the regression does not give positive.
    """
    t = np.asarray(time_s, float) - float(time_s[0])
    theta = np.asarray(motor_angle, float) - float(motor_angle[0])
    u2 = integrate.cumulative_trapezoid(integrate.cumulative_trapezoid(voltage, t, initial=0.0), t, initial=0.0)
    i1 = integrate.cumulative_trapezoid(theta, t, initial=0.0)
    coef = np.linalg.lstsq(np.column_stack([u2, -theta]), i1, rcond=None)[0]
    return tuple(float(c) if c > 0 and math.isfinite(c) else None for c in coef)


def step_mismatch(model, data) -> np.ndarray:
    """ln(model / data) of each feature; :data:`MISSING` where one of them has none."""
    return np.array([0.0 if m is None and d is None else MISSING if m is None or d is None else math.log(m / d)
                     for m, d in zip(model, data)])


def _window(dt, n):
    w = max(5, int(round(SMOOTHING_S / dt)) | 1)
    return min(w, n - 1 if (n - 1) % 2 else n - 2)


def loop_regressors(time_s, output) -> np.ndarray:
    """Columns acceleration, speed, direction of motion and 1 of a position trace."""
    y = np.asarray(output, float)
    dt = float(time_s[-1] - time_s[0]) / (y.size - 1)
    w = _window(dt, y.size)
    v = signal.savgol_filter(y, w, 3, deriv=1, delta=dt)
    a = signal.savgol_filter(y, w, 3, deriv=2, delta=dt)
    return np.column_stack([a, v, np.sign(v), np.ones_like(y)])


def loop_features(time_s, output, current) -> np.ndarray:
    """Coefficients of the current on :func:`loop_regressors` (least squares)."""
    x = loop_regressors(time_s, output)
    i = signal.savgol_filter(np.asarray(current, float), _window(float(time_s[1] - time_s[0]), x.shape[0]), 3)
    return np.linalg.lstsq(x, i, rcond=None)[0]


class LoopScales:
    """Scales of the closed-loop features of one data set: each term's RMS over the
    current's RMS, so a mismatch is each term's error as a share of the current."""

    def __init__(self, time_s, output, current):
        x = loop_regressors(time_s, output)
        self.scale = np.sqrt(np.mean(x ** 2, axis=0)) / max(float(np.sqrt(np.mean(np.square(current)))), 1e-300)

    def mismatch(self, model, data) -> np.ndarray:
        """Scaled differences of two feature vectors."""
        return (np.asarray(model) - np.asarray(data)) * self.scale
