"""Speed and acceleration of the cam drive from shaft-encoder counts: differences or Kalman.

The seed's scheme (section 3, steps 5-6) takes the follower velocity and acceleration by
backward differences, ``v = (s_k - s_{k-1}) / T`` and ``a = (v_k - v_{k-1}) / T``; they lag
by T/2 and T and, from a quantized position, carry the quantization noise amplified by 1/T
and 1/T^2. The drive has a position encoder on the shaft (seed section 2), so this module
offers a Kalman filter on its counts instead (:class:`~servo_toolkit.loop.encoder_estimators.KalmanEstimator`,
filterpy, constant-acceleration model of the cam angle):

* :func:`kalman_scheme` runs the seed's scheme with the encoder counts of the cam angle fed,
  one per step, to the filter; its speed and acceleration estimates w_hat, alpha_hat give the
  follower ``v = s'(theta) w_hat`` and ``a = s''(theta) w_hat^2 + s'(theta) alpha_hat``
  (the ``"corrected"`` scheme keeps ``s'' w_hat^2`` only), the load of eqs 1 and 3, and eq 4
  with ``v / w = s'(theta)``. Everything else (RK4 with M and J frozen, theta by summation)
  is the seed's.
* :func:`compare_on_reference` quantizes the accurate solution's cam angle and compares both
  estimators against its true speed w and acceleration w' (RMS error), next to what the
  quantization step q and sample time T predict: the difference's noise ``q / (T sqrt 6)``
  (two independent uniform errors of variance q^2/12) and lag ``(T/2) rms(w')``; the
  filter's steady-state noise (discrete Lyapunov equation of the fixed-gain filter with
  measurement variance q^2/12) and its model bias (the filter run on the exact angle).

The default encoder (when neither the study nor ``[sensors] motor_encoder_counts`` gives one)
has 4096 counts per revolution; the seed does not state its resolution.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_lyapunov
from ...core.progress import progress_bar

from ...errors import SceneError, SimulationError
from ...loop.encoder_estimators import (EstimationComparison, Estimate, KalmanEstimator, compare_estimators,
                                        encoder_quantum, kalman_estimate, steady_state_gain)
from ...components.cam import kernels
from .voltage_result import Trajectory

#: Values of the study key ``speed_estimator``; the first is the seed's.
ESTIMATORS = ("difference", "kalman")
#: Encoder counts per revolution when neither the study nor the scene states them.
DEFAULT_ENCODER_COUNTS = 4096


def true_acceleration(drive, voltage: float, theta, omega, double_count: bool = False) -> np.ndarray:
    """dw/dt of the continuous model along a trajectory (rad/s^2)."""
    p = kernels.pack(drive)
    return np.array([kernels.rhs(p, float(voltage), float(th), float(w), double_count)[1]
                     for th, w in zip(np.asarray(theta), np.asarray(omega))])


def rms_jerk(acceleration, sample_time: float, settle: int = 0) -> float:
    """RMS of d(acceleration)/dt after ``settle`` samples (rad/s^3): the default jerk level."""
    jerk = np.gradient(np.asarray(acceleration, dtype=float), sample_time)[settle:]
    return float(np.sqrt(np.mean(jerk**2)))


def kalman_scheme(drive, voltage: float, duration: float, step: float, scheme: str = "seed",
                  encoder_counts: int = DEFAULT_ENCODER_COUNTS, jerk: float | None = None,
                  progress: bool = False):
    """The seed's scheme with Kalman estimates from encoder counts instead of differences.

    Parameters
    ----------
    drive : CamDrive
    voltage, duration, step : float
        u (V), run length and step T (s).
    scheme : {"seed", "corrected"}
        As in :func:`~.cam_voltage.discrete_scheme`.
    encoder_counts : int
        Shaft encoder counts per revolution.
    jerk : float
        Kalman jerk level (rad/s^3), e.g. :func:`rms_jerk` of the accurate solution.
    progress : bool
        Show a progress bar.

    Returns
    -------
    Trajectory
        With ``counts`` (encoder counts at every sample, from t = 0) and ``estimate``
        (the filter's angle, speed and acceleration after each count).

    Raises
    ------
    SimulationError
        Clearance (the follower travel is then not a function of the cam angle, so the
        encoder cannot give it), a non-finite speed or the cam reversing.
    """
    if scheme not in ("seed", "corrected"):
        raise ValueError(f"scheme must be 'seed' or 'corrected' (got {scheme!r})")
    if jerk is None or not jerk > 0:
        raise ValueError(f"the Kalman estimator needs a positive jerk level (got {jerk})")
    if drive.cam.clearance > 0:
        raise SimulationError("the Kalman option estimates the follower motion from the cam angle; with "
                              "clearance the travel is not a function of the angle (use differences)")
    n = int(round(duration / step))
    if n < 1 or not step > 0:
        raise SimulationError(f"step {step} s does not fit in a run of {duration} s")
    p = kernels.pack(drive)
    a_, m, jm, mf, gx = p[0], p[1], p[8], p[9], p[3]
    u, h = float(voltage), float(step)
    q = encoder_quantum(int(encoder_counts))
    theta, omega = np.zeros(n + 1), np.zeros(n + 1)
    counts = np.zeros(n + 1, dtype=np.int64)
    est_x = np.zeros((n + 1, 3))
    kf = KalmanEstimator(h, q, jerk, position=0.0)
    est_x[0] = kf.step(0)
    load, inertia = mf, jm
    for k in progress_bar(range(n), show=progress, desc="cam scheme (Kalman)"):
        w = omega[k]
        wn = kernels.speed_step(p, u, w, load, inertia, h)
        if not math.isfinite(wn):
            raise SimulationError("discrete cam scheme (Kalman): non-finite speed")
        if wn < 0:
            why = ("; the seed scheme feeds the follower's inertial force m a s' back explicitly, "
                   "through the filter's acceleration estimate, with a loop gain m s'^2 / J up to "
                   f"{m * 4 * a_**2 / (jm + m * 4 * a_**2):.3f} (at s' = 2 A), which the filter can turn into "
                   "a growing period-2 oscillation: use the corrected scheme, a coarser encoder or a "
                   "lower jerk level" if scheme == "seed" else "")
            raise SimulationError(f"discrete cam scheme (Kalman): the cam reversed (w < 0) at t = "
                                  f"{(k + 1) * h:.4g} s; the shaft-friction model assumes forward rotation{why}")
        omega[k + 1] = wn
        theta[k + 1] = theta[k] + wn * h
        counts[k + 1] = round(theta[k + 1] / q)
        est_x[k + 1] = kf.step(counts[k + 1])
        w_hat, alpha_hat = est_x[k + 1, 1], est_x[k + 1, 2]
        s, d1, d2 = kernels.law(theta[k + 1], a_)
        v = d1 * w_hat
        acc = d2 * w_hat * w_hat + (0.0 if scheme == "corrected" else d1 * alpha_hat)
        force, _ = kernels.friction(p, s, d1, float(np.sign(v)), m * acc - gx, 0.0)
        load = mf + force * d1
        inertia = jm + m * d1 * d1
    t = np.arange(n + 1) * h
    return Trajectory(f"discrete ({scheme}, Kalman)", t, theta, omega, (u - drive.back_emf_constant * omega)
                      / drive.resistance, counts=counts,
                      estimate=Estimate(est_x[:, 0], est_x[:, 1], est_x[:, 2]))


def steady_state_noise(sample_time: float, quantum: float, jerk: float) -> np.ndarray:
    """Standard deviations (angle, speed, acceleration) of the steady-state filter's response
    to white measurement noise of variance ``quantum**2 / 12`` (discrete Lyapunov equation of
    ``x <- (I - K H) F x + K z``)."""
    f, h, k = steady_state_gain(sample_time, quantum, jerk)
    d = np.array([1.0, sample_time, sample_time**2]) / quantum   # dimensionless states
    a = d[:, None] * ((np.eye(3) - np.outer(k, h)) @ f) / d[None, :]
    x = solve_discrete_lyapunov(a, np.outer(d * k, d * k) * quantum**2 / 12.0)
    return np.sqrt(np.diag(x)) / d


@dataclass(frozen=True)
class CamEstimation:
    """Backward differences and the Kalman filter against the accurate solution.

    Attributes
    ----------
    comparison : EstimationComparison
        Both estimators on the quantized accurate cam angle (``truth``: w and w').
    encoder_counts : int
        Counts per revolution.
    exact_kalman : Estimate
        The filter on the unquantized angle: its error is the model bias alone.
    predicted : dict
        ``difference_speed_noise`` q/(T sqrt 6), ``difference_speed_lag`` (T/2) rms(w'),
        ``difference_acceleration_noise`` q/(T^2 sqrt 2), ``difference_acceleration_lag``
        T rms(w''), ``kalman_speed_noise`` and ``kalman_acceleration_noise`` (steady-state
        filter), ``kalman_speed_bias`` and ``kalman_acceleration_bias`` (RMS error on the
        exact angle); rad/s and rad/s^2.
    """

    comparison: EstimationComparison
    encoder_counts: int
    exact_kalman: Estimate
    predicted: dict

    def rms(self, estimator: str, quantity: str) -> float:
        """Measured RMS error of ``"difference"|"kalman"`` for ``"speed"|"acceleration"``."""
        return self.comparison.rms["backward" if estimator == "difference" else estimator][quantity]

    def expected(self, estimator: str, quantity: str) -> float:
        """Noise and lag/bias added in quadrature (independent parts)."""
        pr = self.predicted
        second = "lag" if estimator == "difference" else "bias"
        return math.hypot(pr[f"{estimator}_{quantity}_noise"], pr[f"{estimator}_{quantity}_{second}"])

    def ratio(self, quantity: str) -> float:
        """RMS error of the differences over that of the Kalman filter (> 1: the filter is better)."""
        return self.rms("difference", quantity) / self.rms("kalman", quantity)

    def to_dict(self) -> dict:
        """JSON-ready summary (no time series)."""
        c = self.comparison
        units = {"speed": "rad_s", "acceleration": "rad_s2"}
        out = {"encoder_counts_per_rev": self.encoder_counts, "quantum_rad": c.quantum,
               "sample_time_s": c.sample_time, "kalman_jerk_rad_s3": c.jerk, "settle_samples": c.settle}
        for est in ESTIMATORS:
            out[est] = {}
            for key, unit in units.items():
                out[est][f"rms_{key}_error_{unit}"] = self.rms(est, key)
                out[est][f"expected_rms_{key}_error_{unit}"] = self.expected(est, key)
            out[est]["speed_lag_s"] = c.lag["backward" if est == "difference" else est]["speed"]
        out["predicted"] = {f"{k}_{units[k.split('_')[1]]}": v for k, v in self.predicted.items()}
        out["error_ratio_difference_to_kalman"] = {key: self.ratio(key) for key in units}
        return out

    def table(self) -> str:
        """Plain-text summary."""
        c = self.comparison
        pr = self.predicted
        lines = [f"speed and acceleration from {self.encoder_counts} counts/rev (q = {c.quantum:.4g} rad) "
                 f"at T = {c.sample_time * 1e3:g} ms, Kalman jerk {c.jerk:.3g} rad/s^3; RMS error against "
                 "the accurate solution (expected = noise (+) lag or bias):",
                 f"{'':12s} {'speed [rad/s]':>14s} {'expected':>9s} {'accel [rad/s^2]':>16s} {'expected':>9s}"]
        for est in ESTIMATORS:
            lines.append(f"{est:12s} {self.rms(est, 'speed'):14.4g} {self.expected(est, 'speed'):9.4g} "
                         f"{self.rms(est, 'acceleration'):16.4g} {self.expected(est, 'acceleration'):9.4g}")
        lines.append(f"difference / Kalman: speed {self.ratio('speed'):.2f}x, acceleration "
                     f"{self.ratio('acceleration'):.2f}x (difference noise q/(T sqrt 6) = "
                     f"{pr['difference_speed_noise']:.3g} rad/s, lag (T/2) rms(w') = {pr['difference_speed_lag']:.3g} "
                     f"rad/s; Kalman noise {pr['kalman_speed_noise']:.3g}, bias {pr['kalman_speed_bias']:.3g} rad/s)")
        return "\n".join(lines)

    def plot(self, axes=None, window=None):
        """True speed and acceleration with both estimates (2 rows) over ``window`` (t0, t1)
        in s; by default 0.2 s around the highest speed peak of the record's last third.
        Returns the axes."""
        c = self.comparison
        axes = c.plot(axes)
        if window is None:
            last = c.t >= c.t[0] + (c.t[-1] - c.t[0]) * 2 / 3
            peak = c.t[last][np.argmax(c.truth.speed[last])]
            window = (max(peak - 0.07, c.t[0]), min(peak + 0.13, c.t[-1]))
        t0, t1 = window
        keep = (c.t >= t0) & (c.t <= t1)
        for ax, key in zip(axes, ("speed", "acceleration")):
            ax.set_xlim(t0, t1)
            if keep.any():
                vals = np.concatenate([getattr(e, key)[keep] for e in (c.truth, c.kalman, c.backward)])
                pad = 0.05 * (vals.max() - vals.min() + 1e-12)
                ax.set_ylim(vals.min() - pad, vals.max() + pad)
        axes[0].set_title(f"Cam speed from {self.encoder_counts} counts/rev: true, differences, Kalman")
        return axes


def compare_on_reference(drive, voltage: float, reference, encoder_counts: int = DEFAULT_ENCODER_COUNTS,
                         jerk: float | None = None, settle: int | None = None) -> CamEstimation:
    """Both estimators on the quantized cam angle of an accurate trajectory (uniform samples).

    Parameters
    ----------
    drive : CamDrive
    voltage : float
        u (V), for the true acceleration.
    reference : Trajectory
        The accurate solution sampled at the scheme's step.
    encoder_counts : int
        Counts per revolution.
    jerk : float, optional
        Kalman jerk level (rad/s^3); default :func:`rms_jerk` of the reference after ``settle``.
    settle : int, optional
        Samples skipped before measuring (default a tenth of the record).
    """
    t = np.asarray(reference.t, dtype=float)
    dt = float(t[1] - t[0])
    settle = t.size // 10 if settle is None else int(settle)
    acc = true_acceleration(drive, voltage, reference.theta, reference.omega)
    jerk = rms_jerk(acc, dt, settle) if jerk is None else float(jerk)
    q = encoder_quantum(int(encoder_counts))
    comp = compare_estimators(t, reference.theta, reference.omega, acc, q, jerk=jerk, settle=settle)
    exact = kalman_estimate(reference.theta / q, dt, q, jerk)   # "counts" without rounding
    noise = steady_state_noise(dt, q, jerk)
    s = slice(settle, None)

    def rms(x):
        return float(np.sqrt(np.mean(np.square(x[s]))))
    jerk_true = np.gradient(acc, dt)
    predicted = {"difference_speed_noise": q / (dt * math.sqrt(6.0)),
                 "difference_speed_lag": 0.5 * dt * rms(acc),
                 "difference_acceleration_noise": q / (dt**2 * math.sqrt(2.0)),
                 "difference_acceleration_lag": dt * rms(jerk_true),
                 "kalman_speed_noise": float(noise[1]), "kalman_acceleration_noise": float(noise[2]),
                 "kalman_speed_bias": rms(exact.speed - reference.omega),
                 "kalman_acceleration_bias": rms(exact.acceleration - acc)}
    return CamEstimation(comp, int(encoder_counts), exact, predicted)


def estimation_options(scene, study) -> dict:
    """``speed_estimator``, ``encoder_counts`` and ``kalman_jerk`` of a cam study (keyword
    arguments of :func:`~.cam_voltage.constant_voltage`).

    Study keys: ``speed_estimator = "difference" | "kalman"`` (default ``"difference"``, the
    seed's), ``encoder_counts`` (counts per revolution; default ``[sensors]
    motor_encoder_counts`` or 4096), ``kalman_jerk`` (rad/s^3; default the RMS jerk of the
    accurate solution).

    Raises
    ------
    SceneError
        A value outside those rules.
    """
    get = study.get if study is not None else (lambda key, default=None: default)
    key = study.key if study is not None else (lambda name: name)
    estimator = get("speed_estimator", ESTIMATORS[0])
    if estimator not in ESTIMATORS:
        raise SceneError(key("speed_estimator"), f"must be one of {list(ESTIMATORS)} (got {estimator!r})")
    counts = get("encoder_counts")
    if counts is None:
        counts = scene.sensors.motor_encoder_counts or DEFAULT_ENCODER_COUNTS
    elif isinstance(counts, bool) or not isinstance(counts, (int, np.integer)) or counts < 1:
        raise SceneError(key("encoder_counts"), f"must be a positive integer (counts per revolution, got {counts!r})")
    jerk = get("kalman_jerk")
    if jerk is not None and (isinstance(jerk, (bool, str)) or not float(jerk) > 0 or not math.isfinite(float(jerk))):
        raise SceneError(key("kalman_jerk"), f"must be a positive jerk level in rad/s^3 (got {jerk!r})")
    return {"speed_estimator": estimator, "encoder_counts": int(counts),
            "kalman_jerk": None if jerk is None else float(jerk)}


__all__ = ["ESTIMATORS", "DEFAULT_ENCODER_COUNTS", "CamEstimation", "kalman_scheme", "compare_on_reference",
           "estimation_options", "steady_state_noise", "true_acceleration", "rms_jerk"]
