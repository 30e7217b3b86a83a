"""Position, speed and acceleration from quantized encoder counts.

Two estimators, each with a stateful per-sample ``step(count)`` (for a control loop or the
cam scheme, one call per sample) and a batch function over an array of counts:

* :class:`KalmanEstimator` / :func:`kalman_estimate`: a filterpy ``KalmanFilter`` on the
  constant-acceleration model x = [position, speed, acceleration],
  F = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]], measurement z = count * quantum.
  Process noise: the discrete Wiener-process-acceleration model (Bar-Shalom), i.e. the
  acceleration changes by a white increment each sample whose standard deviation is
  ``jerk * T`` for a stated jerk level (rad/s^3); Q = Gamma Gamma' (jerk T)^2 with
  Gamma = [T^2/2, T, 1] (filterpy ``Q_discrete_white_noise(3, T, (jerk*T)**2)``).
  Measurement noise: the quantization error, uniform over one count, R = quantum^2 / 12.
* :class:`BackwardDifference` / :func:`backward_difference_estimate`: seed 002's scheme,
  v_k = (z_k - z_{k-1}) / T, a_k = (v_k - v_{k-1}) / T (lags T/2 and T; noisy).

:func:`compare_estimators` runs both on a quantized known signal and reports RMS errors and
lags against the truth. A sensible jerk level for a sine of amplitude A at angular frequency
w is its RMS jerk A w^3 / sqrt(2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are
from scipy.optimize import minimize_scalar


def quantize(position, quantum: float) -> np.ndarray:
    """Encoder counts of a position (rounded to the nearest count, so z = count*quantum
    is off by at most quantum/2)."""
    if not quantum > 0:
        raise ValueError(f"quantum must be positive, got {quantum}")
    return np.round(np.asarray(position, dtype=float) / quantum).astype(np.int64)


def encoder_quantum(counts_per_rev: int) -> float:
    """rad per count of an encoder with ``counts_per_rev`` counts per revolution."""
    if counts_per_rev <= 0:
        raise ValueError(f"counts per revolution must be positive, got {counts_per_rev}")
    return 2 * math.pi / counts_per_rev


def white_noise_q(dt: float, var: float) -> np.ndarray:
    """Process noise of the constant-acceleration model driven by a piecewise constant jerk:
    filterpy's ``Q_discrete_white_noise(dim=3, dt=dt, var=var)``, the same expression (and
    numbers) written out, so a run that needs only the filter's gain does not import
    filterpy (which loads scipy.stats)."""
    q = [[.25 * dt**4, .5 * dt**3, .5 * dt**2],
         [.5 * dt**3, dt**2, dt],
         [.5 * dt**2, dt, 1]]
    return np.array(q) * var


def _model(sample_time: float, quantum: float, jerk: float):
    if not (sample_time > 0 and quantum > 0 and jerk > 0):
        raise ValueError("sample_time, quantum and jerk must be positive "
                         f"(got {sample_time}, {quantum}, {jerk})")
    t = sample_time
    f = np.array([[1.0, t, 0.5 * t * t], [0.0, 1.0, t], [0.0, 0.0, 1.0]])
    h = np.array([[1.0, 0.0, 0.0]])
    q = white_noise_q(t, (jerk * t) ** 2)
    r = np.array([[quantum**2 / 12.0]])
    return f, h, q, r


def steady_state_gain(sample_time: float, quantum: float, jerk: float):
    """The fixed-gain form of the Kalman estimator, for compiled loops.

    Returns
    -------
    F, H, K : numpy.ndarray
        Transition (3, 3), measurement (1, 3) and steady-state gain (3,): per sample
        x <- F x; x <- x + K (z - H x).
    """
    f, h, q, r = _model(sample_time, quantum, jerk)
    p = solve_discrete_are(f.T, h.T, q, r)          # a-priori covariance
    k = p @ h.T @ np.linalg.inv(h @ p @ h.T + r)
    return f, h, k.ravel()


def steady_state_covariance(sample_time: float, quantum: float, jerk: float):
    """Steady-state covariances of the Kalman estimator.

    Returns
    -------
    prior, posterior : numpy.ndarray
        (3, 3) before and after the update. A filterpy ``KalmanFilter`` started with
        ``P = posterior`` keeps the gain of :func:`steady_state_gain` from its first step.
    """
    f, h, q, r = _model(sample_time, quantum, jerk)
    prior = solve_discrete_are(f.T, h.T, q, r)
    k = prior @ h.T @ np.linalg.inv(h @ prior @ h.T + r)
    ikh = np.eye(3) - k @ h
    return prior, ikh @ prior @ ikh.T + k @ r @ k.T


def default_jerk(torque_constant: float, current_limit: float, motor_inertia: float, speed_gain: float,
                 sample_time: float) -> float:
    """Jerk level (motor rad/s^3) for the Kalman filter's process noise: the motor reaching its
    peak acceleration ``a_max = Kt I_max / J_m`` within one speed-loop time constant
    ``1 / w_c``, ``w_c = Kv Kt / J_m`` from the speed path's gain ``speed_gain`` (A per motor
    rad/s; ``0.2 pi / Ts``, a tenth of the sample rate, when it is 0)."""
    a_max = torque_constant * current_limit / motor_inertia
    kv = abs(speed_gain)
    wc = kv * torque_constant / motor_inertia if kv > 0 else 0.2 * math.pi / sample_time
    return a_max * wc


def speed_response(F, K, sample_time: float, frequencies) -> np.ndarray:
    """Complex ratio speed estimate / true speed of the constant-gain filter
    (:func:`steady_state_gain`) for a sinusoidal angle at ``frequencies`` (Hz), quantization
    left out."""
    a = (np.eye(3) - np.outer(K, [1.0, 0.0, 0.0])) @ F
    out = []
    for f in np.atleast_1d(frequencies):
        z = np.exp(2j * math.pi * f * sample_time)
        x = np.linalg.solve(z * np.eye(3) - a, K * z)
        out.append(x[1] / (2j * math.pi * f))
    return np.array(out)


def speed_noise_rms(kind: str, quantum: float, sample_time: float, F=None, K=None) -> float:
    """RMS speed-estimate noise (rad/s) from quantization alone, the angle error taken as
    white and uniform over one count (variance q^2/12): q / (sqrt(6) Ts) for the difference,
    (q / sqrt(12)) ||h|| for the filter, h the impulse response of its speed output to the
    measurement."""
    if kind == "difference":
        return quantum / (math.sqrt(6.0) * sample_time)
    a = (np.eye(3) - np.outer(K, [1.0, 0.0, 0.0])) @ F
    x, acc = np.asarray(K, dtype=float).copy(), 0.0
    for _ in range(100_000):
        acc += x[1] ** 2
        x = a @ x
        if abs(x[1]) < 1e-14 * math.sqrt(acc):
            break
    return quantum / math.sqrt(12.0) * math.sqrt(acc)


class KalmanEstimator:
    """Per-sample Kalman estimator (filterpy) of position, speed and acceleration.

    Parameters
    ----------
    sample_time : float
        s.
    quantum : float
        rad (or m) per count.
    jerk : float
        Jerk level (rad/s^3) setting the process noise (module docstring).
    position, speed, acceleration : float
        Initial estimate; the initial covariance is wide (1 count, and speed/acceleration
        uncertain by the stated jerk over 1 s), so the filter settles from the data.

    Examples
    --------
    >>> est = KalmanEstimator(1e-3, 2 * math.pi / 4096, jerk=100.0)
    >>> p, v, a = est.step(0)
    """

    def __init__(self, sample_time: float, quantum: float, jerk: float, *, position: float = 0.0,
                 speed: float = 0.0, acceleration: float = 0.0):
        self.sample_time, self.quantum, self.jerk = float(sample_time), float(quantum), float(jerk)
        from filterpy.kalman import KalmanFilter
        f, h, q, r = _model(self.sample_time, self.quantum, self.jerk)
        self.filter = KalmanFilter(dim_x=3, dim_z=1)
        self.filter.F, self.filter.H, self.filter.Q, self.filter.R = f, h, q, r
        self.reset(position, speed, acceleration)

    def reset(self, position: float = 0.0, speed: float = 0.0, acceleration: float = 0.0) -> None:
        """Restart from an estimate with the wide initial covariance."""
        self.filter.x = np.array([[position], [speed], [acceleration]], dtype=float)
        self.filter.P = np.diag([self.quantum**2, self.jerk**2, (self.jerk * 10.0) ** 2])

    def step(self, count) -> tuple[float, float, float]:
        """Predict one sample and update with an encoder count; returns (position, speed,
        acceleration)."""
        self.filter.predict()
        self.filter.update(np.array([[float(count) * self.quantum]]))
        x = self.filter.x[:, 0]
        return float(x[0]), float(x[1]), float(x[2])

    @property
    def state(self) -> np.ndarray:
        """Current estimate [position, speed, acceleration]."""
        return self.filter.x[:, 0].copy()


class BackwardDifference:
    """Per-sample backward differences of encoder positions (seed 002's scheme).

    The first sample gives zero speed, the first two zero acceleration.
    """

    def __init__(self, sample_time: float, quantum: float):
        if not (sample_time > 0 and quantum > 0):
            raise ValueError("sample_time and quantum must be positive")
        self.sample_time, self.quantum = float(sample_time), float(quantum)
        self.reset()

    def reset(self) -> None:
        """Forget the history."""
        self._z = None
        self._v = None

    def step(self, count) -> tuple[float, float, float]:
        """(position, speed, acceleration) after one more count."""
        z = float(count) * self.quantum
        v = 0.0 if self._z is None else (z - self._z) / self.sample_time
        a = 0.0 if self._v is None else (v - self._v) / self.sample_time
        self._z, self._v = z, v
        return z, v, a


@dataclass(frozen=True)
class Estimate:
    """Estimated position, speed and acceleration over samples (arrays)."""

    position: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray


def kalman_estimate(counts, sample_time: float, quantum: float, jerk: float) -> Estimate:
    """Kalman estimates over an array of counts (filterpy ``batch_filter``); the same numbers
    as calling :meth:`KalmanEstimator.step` per sample from a zero initial estimate at the
    first count's position."""
    counts = np.asarray(counts)
    est = KalmanEstimator(sample_time, quantum, jerk, position=float(counts[0]) * quantum if counts.size else 0.0)
    if counts.size == 0:
        empty = np.zeros(0)
        return Estimate(empty, empty, empty)
    means, _, _, _ = est.filter.batch_filter(counts.astype(float)[:, None] * quantum)
    x = means[:, :, 0]
    return Estimate(x[:, 0], x[:, 1], x[:, 2])


def backward_difference_estimate(counts, sample_time: float, quantum: float) -> Estimate:
    """Backward differences over an array of counts (same numbers as the per-sample form)."""
    z = np.asarray(counts, dtype=float) * quantum
    v = np.zeros_like(z)
    v[1:] = np.diff(z) / sample_time
    a = np.zeros_like(z)
    a[2:] = np.diff(v[1:]) / sample_time
    return Estimate(z, v, a)


def _lag(t, truth, estimate, start: int, max_lag: float) -> float:
    """Delay tau (s) minimizing RMS(estimate(t) - truth(t - tau)) over [0, max_lag], measured
    from sample ``start`` on (``t[start] - max_lag`` must lie inside the record)."""
    ts, es = t[start:], estimate[start:]

    def cost(tau):
        return float(np.mean((es - np.interp(ts - tau, t, truth)) ** 2))
    return float(minimize_scalar(cost, bounds=(0.0, max_lag), method="bounded",
                                 options={"xatol": max_lag * 1e-6}).x)


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


@dataclass(frozen=True)
class EstimationComparison:
    """Kalman filter against backward differences on a known signal.

    Attributes
    ----------
    t : numpy.ndarray
        Sample times (s).
    truth, kalman, backward : Estimate
    quantum, sample_time, jerk : float
    settle : int
        Samples skipped at the start before the errors are measured.
    rms : dict
        ``{"kalman"|"backward": {"position"|"speed"|"acceleration": rms error}}``.
    lag : dict
        Same layout, delay (s) of each estimate behind the truth.
    """

    t: np.ndarray
    truth: Estimate
    kalman: Estimate
    backward: Estimate
    quantum: float
    sample_time: float
    jerk: float
    settle: int
    rms: dict
    lag: dict

    def to_dict(self) -> dict:
        """JSON-ready summary (no time series)."""
        units = {"position": "rad", "speed": "rad_s", "acceleration": "rad_s2"}
        out = {"quantum_rad": self.quantum, "sample_time_s": self.sample_time, "jerk_rad_s3": self.jerk,
               "settle_samples": self.settle}
        for name in ("kalman", "backward"):
            out[name] = {**{f"rms_{k}_error_{u}": self.rms[name][k] for k, u in units.items()},
                         **{f"{k}_lag_s": self.lag[name][k] for k in units}}
        return out

    def plot(self, axes=None):
        """Speed and acceleration: truth and both estimates; returns the axes (2 rows)."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
        for ax, key, unit in ((axes[0], "speed", "rad/s"), (axes[1], "acceleration", "rad/s^2")):
            ax.plot(self.t, getattr(self.backward, key), lw=0.6, alpha=0.6, label="backward differences")
            ax.plot(self.t, getattr(self.kalman, key), lw=1.2, label="Kalman filter")
            ax.plot(self.t, getattr(self.truth, key), "k--", lw=1.0, label="true")
            ax.set_ylabel(f"{key} [{unit}]")
            ax.grid(True, alpha=0.3)
        axes[0].legend(fontsize="small")
        axes[1].set_xlabel("t [s]")
        return axes


def compare_estimators(t, position, speed, acceleration, quantum: float, jerk: float | None = None,
                       settle: int | None = None) -> EstimationComparison:
    """Quantize a known signal and compare both estimators against it.

    Parameters
    ----------
    t : array_like
        Uniform sample times (s).
    position, speed, acceleration : array_like
        The true signal at ``t``.
    quantum : float
        rad per count.
    jerk : float, optional
        Kalman jerk level; default the RMS of the true signal's jerk (from its acceleration).
    settle : int, optional
        Samples skipped before measuring errors; default 10 % of the record.

    Returns
    -------
    EstimationComparison
    """
    t = np.asarray(t, dtype=float)
    dt = float(t[1] - t[0])
    if not np.allclose(np.diff(t), dt, rtol=1e-6, atol=0):
        raise ValueError("sample times must be uniform")
    truth = Estimate(*(np.asarray(a, dtype=float) for a in (position, speed, acceleration)))
    if jerk is None:
        jerk = _rms(np.gradient(truth.acceleration, dt))
    counts = quantize(truth.position, quantum)
    kf = kalman_estimate(counts, dt, quantum, jerk)
    bd = backward_difference_estimate(counts, dt, quantum)
    settle = t.size // 10 if settle is None else int(settle)
    s = slice(settle, None)
    rms, lag = {}, {}
    max_lag = max(min(t[settle] - t[0], 200 * dt), dt)
    for name, est in (("kalman", kf), ("backward", bd)):
        rms[name], lag[name] = {}, {}
        for key in ("position", "speed", "acceleration"):
            e, x = getattr(est, key)[s], getattr(truth, key)
            rms[name][key] = _rms(e - x[s])
            lag[name][key] = _lag(t, x, getattr(est, key), settle, max_lag)
    return EstimationComparison(t, truth, kf, bd, float(quantum), dt, float(jerk), settle, rms, lag)


__all__ = ["KalmanEstimator", "BackwardDifference", "Estimate", "EstimationComparison", "quantize",
           "encoder_quantum", "kalman_estimate", "backward_difference_estimate", "compare_estimators",
           "default_jerk", "speed_noise_rms", "speed_response", "steady_state_gain", "steady_state_covariance"]
