"""Constant armature voltage on the cam drive: the seed's discrete scheme and an accurate solver.

The continuous model (inductance neglected, seed 002 eqs 9-12) is

    J(theta) w' + (1/2) J'(theta) w^2 = c_m i - M_f - M_g,   i = (u - c_e w) / R,

where ``M_g = (sign(v) f - G_x) ds/dtheta`` holds the guide friction and gravity (the
inertial part ``m a ds/dtheta`` of eq 3 is the variable-inertia term on the left). The guide
friction depends on the follower acceleration, hence on w'; the right-hand side resolves
that with the same contraction as :meth:`CamDrive.follower_force`.

The seed's scheme (section 3) instead steps w by RK4 with J and M frozen at step k, sums
theta, takes s from the law and eqs 6-8, v and a by backward differences, and recomputes M
and J = J_m + m (v/w)^2 for the next step. As printed it counts the follower inertia twice
(m (ds/dtheta)^2 in J *and* m a in M), so as T shrinks it converges, at first order, to a
different continuous model ((J_m + 2 m s'^2) w' + m s' s'' w^2 = ...); the ``"corrected"``
scheme keeps only the velocity-squared part of m a s' and converges to the model above.
:func:`constant_voltage` reports both against the accurate solution for halved steps.

The differenced v and a can be replaced by a Kalman filter on the shaft encoder's counts
(``speed_estimator="kalman"``, :mod:`.cam_estimation`); the default is the seed's
differences. Either way the study compares both estimators with the accurate solution's true
speed and acceleration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import SimulationError
from . import cam_kernels as kernels
from .cam import CamDrive
from .cam_estimation import DEFAULT_ENCODER_COUNTS, ESTIMATORS, compare_on_reference, kalman_scheme


@dataclass(frozen=True)
class Trajectory:
    """A constant-voltage run: time (s), cam angle (rad), speed (rad/s), current (A); runs
    with the Kalman estimator also hold the encoder ``counts`` and the filter's ``estimate``."""

    method: str
    t: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    current: np.ndarray
    counts: np.ndarray | None = None
    estimate: object = None


def steady_speed_without_follower(drive: CamDrive, voltage: float) -> float:
    """Closed form (c_m u - R M_f) / (c_e c_m): the speed with the follower removed (rad/s)."""
    return ((drive.torque_constant * voltage - drive.resistance * drive.shaft_friction)
            / (drive.back_emf_constant * drive.torque_constant))


SCHEMES = ("seed", "corrected")


def discrete_scheme(drive: CamDrive, voltage: float, duration: float, step: float,
                    scheme: str = "seed", speed_estimator: str = "difference",
                    encoder_counts: int | None = None, jerk: float | None = None) -> Trajectory:
    """The seed's fixed-step scheme (section 3), started from rest at theta = 0.

    Parameters
    ----------
    drive : CamDrive
    voltage : float
        Armature voltage u (V).
    duration, step : float
        Run length and step T (s).
    scheme : {"seed", "corrected"}
        ``"seed"`` as printed: J of eq 4 on the left of eq 12 *and* ``m a`` in the load of
        eq 3, which counts the follower inertia twice; ``"corrected"`` keeps only the
        velocity-squared part ``m s' s'' w^2`` of ``m a s'`` (``a`` minus ``s' dw/dt``, both
        by backward differences), so that the scheme converges to the continuous model.
    speed_estimator : {"difference", "kalman"}
        ``"difference"`` (the seed's): v and a by backward differences of the follower
        travel; ``"kalman"``: a Kalman filter on the shaft encoder's counts of the cam angle
        (:func:`~.cam_estimation.kalman_scheme`, which needs ``encoder_counts`` (default
        4096 per revolution) and the jerk level ``jerk`` in rad/s^3).

    Raises
    ------
    SimulationError
        Non-finite speed, or the cam reversing (the shaft-friction model assumes w >= 0).
    """
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES} (got {scheme!r})")
    if speed_estimator not in ESTIMATORS:
        raise ValueError(f"speed_estimator must be one of {ESTIMATORS} (got {speed_estimator!r})")
    if speed_estimator == "kalman":
        return kalman_scheme(drive, voltage, duration, step, scheme, encoder_counts or DEFAULT_ENCODER_COUNTS,
                             jerk)
    n = int(round(duration / step))
    if n < 1 or not step > 0:
        raise SimulationError(f"step {step} s does not fit in a run of {duration} s")
    theta, omega, status = kernels.discrete(kernels.pack(drive), float(voltage), n, float(step),
                                            scheme == "corrected")
    if status == 1:
        raise SimulationError("discrete cam scheme: non-finite speed")
    if status == 2:
        raise SimulationError("discrete cam scheme: the cam reversed (w < 0); the shaft-friction "
                              "model assumes forward rotation")
    t = np.arange(n + 1) * step
    return Trajectory(f"discrete ({scheme})", t, theta, omega,
                      (voltage - drive.back_emf_constant * omega) / drive.resistance)


def accurate(drive: CamDrive, voltage: float, duration: float, t_eval=None, rtol: float = 1e-10,
             double_count: bool = False) -> Trajectory:
    """The continuous model by scipy ``solve_ivp`` (DOP853), started from rest at theta = 0.

    ``double_count=True`` integrates the continuous limit of the seed's printed scheme
    (follower inertia in both J and m a), to separate its modelling error from its
    discretization error.

    Raises
    ------
    SimulationError
        With clearance (its continuous limit is an impact, which this rigid model does not
        describe; the discrete scheme handles clearance), when the cam reverses, or when the
        solver fails.
    """
    if drive.cam.clearance > 0:
        raise SimulationError("the accurate cam solver assumes rigid contact (clearance = 0); "
                              "use the discrete scheme for a cam with clearance")
    p = kernels.pack(drive)
    u = float(voltage)

    def fun(_t, y):
        return kernels.rhs(p, u, y[0], y[1], double_count)

    def reversed_(_t, y):
        return y[1] + 1e-9
    reversed_.terminal = True
    sol = solve_ivp(fun, (0.0, duration), [0.0, 0.0], method="DOP853", rtol=rtol, atol=1e-12,
                    t_eval=t_eval, events=reversed_)
    if sol.status == 1:
        raise SimulationError(f"the cam reversed at t = {sol.t_events[0][0]:.4g} s; the shaft-friction "
                              "model assumes forward rotation")
    if not sol.success or not np.all(np.isfinite(sol.y)):
        raise SimulationError(f"accurate cam solver failed: {sol.message}")
    omega = sol.y[1]
    return Trajectory("accurate", sol.t, sol.y[0], omega,
                      (voltage - drive.back_emf_constant * omega) / drive.resistance)


@dataclass(frozen=True)
class CamVoltageResult:
    """The constant-voltage run by the seed's scheme and the accurate solver, compared.

    Attributes
    ----------
    voltage : float
    reference : Trajectory
        Accurate solution of the continuous model, at the study's sample times.
    seed, corrected : Trajectory
        The seed's scheme as printed, and with the double-counted inertia removed, at the
        study step.
    seed_limit : Trajectory
        Accurate solution of the printed scheme's continuous limit (follower inertia twice).
    steps : numpy.ndarray
        Steps T of the convergence check (s).
    errors : dict of str to numpy.ndarray
        max |w - w_ref| over the start-up window (the first ``window`` seconds) for each
        step (rad/s): ``"seed"`` and ``"corrected"`` against the continuous model,
        ``"seed_vs_limit"`` against its own limit.
    angle_errors : dict of str to numpy.ndarray
        |theta - theta_ref| at the end of the whole run (rad), same keys. Over many turns
        the speed spikes (J drops 45x where ds/dtheta = 0) shift in phase, so the pointwise
        speed error saturates long before the step is small; the end angle measures the
        accumulated drift instead.
    window : float
        Start-up window of ``errors`` (s).
    no_follower_speed : float
        Closed-form speed with the follower removed (rad/s).
    method : str
        The method the caller asked for (every method is always run).
    estimation : CamEstimation or None
        Backward differences and the Kalman filter on the encoder counts of the accurate
        cam angle, against its true speed and acceleration.
    speed_estimator : str
        ``"difference"`` (the seed's) or ``"kalman"``: what the scheme used for v and a.
    kalman : dict of str to Trajectory, optional
        With ``speed_estimator="kalman"``: the ``"seed"`` and ``"corrected"`` schemes run
        with the Kalman estimates (the difference runs above stay for comparison).
    kalman_failures : dict of str to str, optional
        Kalman runs that stopped, with the reason (the seed scheme can go unstable, see
        :func:`~.cam_estimation.kalman_scheme`).
    """

    voltage: float
    reference: Trajectory
    seed: Trajectory
    corrected: Trajectory
    seed_limit: Trajectory
    steps: np.ndarray
    errors: dict
    angle_errors: dict
    window: float
    no_follower_speed: float
    method: str = "both"
    estimation: object = None
    speed_estimator: str = "difference"
    kalman: dict | None = None
    kalman_failures: dict | None = None

    @property
    def difference(self) -> np.ndarray:
        """w_seed - w_accurate at the study's times (rad/s)."""
        return self.seed.omega - self.reference.omega

    def orders(self, key: str) -> np.ndarray:
        """Observed convergence orders log(e(T) / e(T/2)) / log 2 between successive steps."""
        e = self.errors[key]
        return np.log(e[:-1] / e[1:]) / np.log(self.steps[:-1] / self.steps[1:])

    @staticmethod
    def mean_speed(trajectory: Trajectory) -> float:
        """Mean speed over the last full cam turn (rad/s)."""
        turn = trajectory.theta[-1] - 2 * math.pi
        if turn <= 0:
            return float(np.mean(trajectory.omega))
        i = int(np.searchsorted(trajectory.theta, turn))
        return float((trajectory.theta[-1] - trajectory.theta[i]) / (trajectory.t[-1] - trajectory.t[i]))

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        d = self.difference
        runs = {"accurate": self.reference, "seed": self.seed, "corrected": self.corrected,
                "seed_limit": self.seed_limit}
        return {
            "study": "constant_voltage", "voltage_V": self.voltage, "method": self.method,
            "step_s": float(self.seed.t[1] - self.seed.t[0]),
            "t_s": self.seed.t.tolist(),
            **{f"omega_{k}_rad_s": r.omega.tolist() for k, r in runs.items()},
            **{f"mean_speed_{k}_rad_s": self.mean_speed(r) for k, r in runs.items()},
            "max_abs_difference_seed_minus_accurate_rad_s": float(np.abs(d).max()),
            "rms_difference_seed_minus_accurate_rad_s": float(np.sqrt(np.mean(d**2))),
            "no_follower_speed_rad_s": self.no_follower_speed,
            "convergence_window_s": self.window,
            "convergence": [{"step_s": float(h),
                             **{f"startup_max_abs_error_{k}_rad_s": float(e[i]) for k, e in self.errors.items()},
                             **{f"end_angle_error_{k}_rad": float(e[i]) for k, e in self.angle_errors.items()}}
                            for i, h in enumerate(self.steps)],
            "observed_orders": {k: self.orders(k).tolist() for k in self.errors},
            "speed_estimator": self.speed_estimator,
            **({"estimation": self.estimation.to_dict()} if self.estimation is not None else {}),
            **{k: v for name, run in (self.kalman or {}).items() for k, v in self._kalman_dict(name, run).items()},
            **({"kalman_failures": dict(self.kalman_failures)} if self.kalman_failures else {}),
        }

    def _kalman_dict(self, name: str, run: Trajectory) -> dict:
        d = run.omega - self.reference.omega
        return {f"omega_{name}_kalman_rad_s": run.omega.tolist(),
                f"mean_speed_{name}_kalman_rad_s": self.mean_speed(run),
                f"max_abs_difference_{name}_kalman_minus_accurate_rad_s": float(np.abs(d).max()),
                f"rms_difference_{name}_kalman_minus_accurate_rad_s": float(np.sqrt(np.mean(d**2)))}

    def table(self) -> str:
        """Plain-text summary."""
        d = self.difference
        last = self.reference.t >= self.reference.t[-1] - 1
        lines = [f"cam drive at {self.voltage:g} V for {self.reference.t[-1]:g} s "
                 f"(follower removed: {self.no_follower_speed:.2f} rad/s)",
                 f"mean speed over the last turn [rad/s]: accurate {self.mean_speed(self.reference):.4f}, "
                 f"seed scheme {self.mean_speed(self.seed):.4f}, corrected scheme "
                 f"{self.mean_speed(self.corrected):.4f}, seed's continuous limit {self.mean_speed(self.seed_limit):.4f}",
                 f"speed ripple over the last second (accurate): {np.ptp(self.reference.omega[last]):.3f} rad/s",
                 f"seed scheme - accurate: max {np.abs(d).max():.4g} rad/s, rms {np.sqrt(np.mean(d**2)):.4g} rad/s",
                 f"max |w - w_ref| [rad/s] over the first {self.window:g} s against the step T "
                 "(order = observed convergence order), and |theta - theta_ref| [rad] at the end:",
                 f"{'T [ms]':>8s} {'seed vs accurate':>17s} {'corrected':>10s} {'order':>6s} "
                 f"{'seed vs its limit':>18s} {'order':>6s} {'end angle: seed':>16s} {'corrected':>10s}"]
        oc = [math.nan, *self.orders("corrected")]
        ol = [math.nan, *self.orders("seed_vs_limit")]
        for i, h in enumerate(self.steps):
            lines.append(f"{h * 1e3:8.4g} {self.errors['seed'][i]:17.4g} {self.errors['corrected'][i]:10.4g} "
                         f"{oc[i]:6.2f} {self.errors['seed_vs_limit'][i]:18.4g} {ol[i]:6.2f} "
                         f"{self.angle_errors['seed'][i]:16.4g} {self.angle_errors['corrected'][i]:10.4g}")
        for name, run in (self.kalman or {}).items():
            d = run.omega - self.reference.omega
            lines.append(f"{name} scheme with Kalman estimates: mean speed {self.mean_speed(run):.4f} rad/s, "
                         f"- accurate: max {np.abs(d).max():.4g} rad/s, rms {np.sqrt(np.mean(d**2)):.4g} rad/s")
        for name, why in (self.kalman_failures or {}).items():
            lines.append(f"{name} scheme with Kalman estimates stopped: {why}")
        if self.estimation is not None:
            lines.append(self.estimation.table())
        return "\n".join(lines)

    def plot(self, ax=None):
        """Speed by every method and the error against the step; returns the axes."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(1, 2, figsize=(11, 3.8))
        ax[0].plot(self.reference.t, self.reference.omega, lw=1.2, label="accurate (solve_ivp)")
        ax[0].plot(self.seed.t, self.seed.omega, "--", lw=1, label="seed's discrete scheme")
        ax[0].plot(self.corrected.t, self.corrected.omega, ":", lw=1, label="corrected scheme")
        for name, run in (self.kalman or {}).items():
            ax[0].plot(run.t, run.omega, lw=0.8, alpha=0.8, label=f"{name} scheme, Kalman estimates")
        ax[0].axhline(self.no_follower_speed, color="gray", lw=0.8, label="follower removed")
        ax[0].set_xlabel("time [s]")
        ax[0].set_ylabel("speed [rad/s]")
        ax[0].set_title(f"Cam drive at {self.voltage:g} V")
        ax[0].legend(fontsize="small")
        labels = {"seed": "seed vs accurate", "corrected": "corrected vs accurate",
                  "seed_vs_limit": "seed vs its own limit"}
        for k, e in self.errors.items():
            ax[1].loglog(self.steps * 1e3, e, "o-", label=labels[k])
        ax[1].set_xlabel("step T [ms]")
        ax[1].set_ylabel(f"max |w - w_ref| in the first {self.window:g} s [rad/s]")
        ax[1].set_title("Discrete scheme error")
        ax[1].legend(fontsize="small")
        return ax

    def plot_estimation(self, axes=None, window=None):
        """True, differenced and Kalman-filtered speed and acceleration (2 rows) over
        ``window`` (t0, t1) s (default 0.2 s around a late speed peak); returns the axes."""
        if self.estimation is None:
            raise ValueError("this result has no estimator comparison")
        return self.estimation.plot(axes, window)


def constant_voltage(drive: CamDrive, voltage: float, duration: float, step: float,
                     refinements: int = 3, method: str | None = None,
                     window: float | None = None, speed_estimator: str = "difference",
                     encoder_counts: int | None = None, kalman_jerk: float | None = None) -> CamVoltageResult:
    """Run the constant-voltage study by every method and check convergence.

    Parameters
    ----------
    drive : CamDrive
    voltage, duration, step : float
        u (V), run length (s) and the study's step T (s).
    refinements : int
        The convergence check uses steps ``4 T, 2 T, T, T/2, ...`` (``refinements`` halvings
        below 4 T).
    method : str, optional
        Recorded in the result; every method always runs.
    window : float, optional
        Start-up window of the pointwise speed error (s); default a tenth of the run.
    speed_estimator : {"difference", "kalman"}
        What the scheme uses for the follower speed and acceleration; ``"difference"`` is
        the seed's. With ``"kalman"`` the seed and corrected schemes also run with the
        Kalman filter (result field ``kalman``); the convergence ladder always uses the
        seed's differences. Both estimators are compared on the accurate solution either way.
    encoder_counts : int, optional
        Shaft encoder counts per revolution (default 4096).
    kalman_jerk : float, optional
        Kalman jerk level (rad/s^3); default the RMS jerk of the accurate solution.
    """
    if speed_estimator not in ESTIMATORS:
        raise ValueError(f"speed_estimator must be one of {ESTIMATORS} (got {speed_estimator!r})")
    encoder_counts = encoder_counts or DEFAULT_ENCODER_COUNTS
    window = 0.1 * duration if window is None else min(window, duration)
    steps = 4 * step / 2.0 ** np.arange(refinements + 1)
    times = np.arange(int(round(duration / steps[-1])) + 1) * steps[-1]
    times = times[times <= duration]
    ref = accurate(drive, voltage, duration, t_eval=times)
    limit = accurate(drive, voltage, duration, t_eval=times, double_count=True)
    errors = {"seed": [], "corrected": [], "seed_vs_limit": []}
    angles = {"seed": [], "corrected": [], "seed_vs_limit": []}
    for h in steps:
        seed = discrete_scheme(drive, voltage, duration, h, "seed")
        corr = discrete_scheme(drive, voltage, duration, h, "corrected")
        for key, run, against in (("seed", seed, ref), ("corrected", corr, ref), ("seed_vs_limit", seed, limit)):
            errors[key].append(_error(run, against, window))
            angles[key].append(abs(run.theta[-1] - np.interp(run.t[-1], against.t, against.theta)))
    seed = discrete_scheme(drive, voltage, duration, step, "seed")
    corr = discrete_scheme(drive, voltage, duration, step, "corrected")
    estimation = compare_on_reference(drive, voltage, accurate(drive, voltage, duration, t_eval=seed.t),
                                      encoder_counts, kalman_jerk)
    kalman, failures = None, None
    if speed_estimator == "kalman":
        kalman, failures = {}, {}
        for name in SCHEMES:
            try:
                kalman[name] = kalman_scheme(drive, voltage, duration, step, name, encoder_counts,
                                             estimation.comparison.jerk)
            except SimulationError as exc:
                failures[name] = str(exc)
    return CamVoltageResult(voltage, _at(ref, seed.t), seed, corr, _at(limit, seed.t), steps,
                            {k: np.array(v) for k, v in errors.items()},
                            {k: np.array(v) for k, v in angles.items()}, window,
                            steady_speed_without_follower(drive, voltage), method or "both",
                            estimation, speed_estimator, kalman, failures or None)


def _at(traj: Trajectory, t) -> Trajectory:
    return Trajectory(traj.method, t, np.interp(t, traj.t, traj.theta), np.interp(t, traj.t, traj.omega),
                      np.interp(t, traj.t, traj.current))


def _error(run: Trajectory, ref: Trajectory, window: float) -> float:
    keep = run.t <= window + 1e-12
    return float(np.abs(run.omega[keep] - np.interp(run.t[keep], ref.t, ref.omega)).max())
