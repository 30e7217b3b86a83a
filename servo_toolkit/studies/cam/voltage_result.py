"""Results of the cam drive's constant-voltage study (:mod:`.cam_voltage`): trajectories and
the comparison of the seed's scheme with the accurate solver."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


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


@dataclass(frozen=True)
class CamVoltageResult:
    """The constant-voltage run by the seed's scheme and the accurate solver, compared.

    Attributes
    ----------
    voltage : float
    reference : Trajectory or None
        Accurate solution of the continuous model, at the study's sample times; None when
        the accurate comparison is skipped (see ``skipped``).
    seed, corrected : Trajectory
        The seed's scheme as printed, and with the double-counted inertia removed, at the
        study step (with the clearance hysteresis of eqs 6-8 when the cam has clearance).
    seed_limit : Trajectory or None
        Accurate solution of the printed scheme's continuous limit (follower inertia twice).
    steps : numpy.ndarray
        Steps T of the convergence check (s); empty when the comparison is skipped.
    errors : dict of str to numpy.ndarray
        max |w - w_ref| over the start-up window (the first ``window`` seconds) for each
        step (rad/s): ``"seed"`` and ``"corrected"`` against the continuous model,
        ``"seed_vs_limit"`` against its own limit. NaN where the run at that step failed
        (see ``ladder_failures``).
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
    ladder_failures : tuple of (float, str, str)
        Runs of the convergence check that stopped: (step T in s, scheme, reason). A large
        step can make the explicit scheme reverse the cam; that step's errors are NaN.
    skipped : str or None
        Why the accurate comparison (reference, continuous limit, convergence check and
        estimator comparison) was not run: the cam has clearance, whose continuous limit is
        an impact that the rigid accurate model does not describe.
    clearance : float
        Half the cam/roller play c of the runs (m).
    scheme_failures : dict of str to str, optional
        With clearance: a scheme that stopped at the study step (the cam reversed), with
        the reason; its trajectory then ends at the stop, and the other scheme's result
        stands on its own.
    conditioning : dict of str to dict, optional
        With clearance, per scheme that ran through: how much relative voltage changes of
        +-1e-12 move its speed trace (``max_speed_change_rad_s``), the relative condition
        number (that change over max |w|, over 1e-12) and ``ill_conditioned`` (above 1e6:
        the impacts in the clearance make the speed irreproducible).
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
    ladder_failures: tuple = ()
    skipped: str | None = None
    clearance: float = 0.0
    scheme_failures: dict | None = None
    conditioning: dict | None = None

    @property
    def difference(self) -> np.ndarray | None:
        """w_seed - w_accurate at the study's times (rad/s); None without the reference."""
        return None if self.reference is None else self.seed.omega - self.reference.omega

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
        """JSON-ready dictionary (failed convergence runs give null errors)."""
        runs = {"seed": self.seed, "corrected": self.corrected}
        if self.reference is not None:
            runs = {"accurate": self.reference, **runs, "seed_limit": self.seed_limit}
        out = {
            "study": "constant_voltage", "voltage_V": self.voltage, "method": self.method,
            "step_s": float(self.seed.t[1] - self.seed.t[0]),
            "t_s": max((r.t for r in runs.values()), key=len).tolist(),
            **{f"omega_{k}_rad_s": r.omega.tolist() for k, r in runs.items()},
            **{f"mean_speed_{k}_rad_s": self.mean_speed(r) for k, r in runs.items()},
        }
        d = self.difference
        if d is not None:
            out["max_abs_difference_seed_minus_accurate_rad_s"] = float(np.abs(d).max())
            out["rms_difference_seed_minus_accurate_rad_s"] = float(np.sqrt(np.mean(d**2)))
        out.update({
            "no_follower_speed_rad_s": self.no_follower_speed,
            "clearance_m": self.clearance,
            "accurate_comparison": "skipped: " + self.skipped if self.skipped else "run",
            "scheme_failures": dict(self.scheme_failures or {}),
            **({"conditioning": {k: {n: _finite(x) if isinstance(x, float) else x for n, x in c.items()}
                                 for k, c in self.conditioning.items()}} if self.conditioning else {}),
            "convergence_window_s": self.window,
            "convergence": [{"step_s": float(h),
                             **{f"startup_max_abs_error_{k}_rad_s": _finite(e[i]) for k, e in self.errors.items()},
                             **{f"end_angle_error_{k}_rad": _finite(e[i]) for k, e in self.angle_errors.items()},
                             "failures": {name: why for step, name, why in self.ladder_failures if step == h}}
                            for i, h in enumerate(self.steps)],
            "observed_orders": {k: [_finite(x) for x in self.orders(k)] for k in self.errors},
            "speed_estimator": self.speed_estimator,
            **({"estimation": self.estimation.to_dict()} if self.estimation is not None else {}),
            **{k: v for name, run in (self.kalman or {}).items() for k, v in self._kalman_dict(name, run).items()},
            **({"kalman_failures": dict(self.kalman_failures)} if self.kalman_failures else {}),
        })
        return out

    def _kalman_dict(self, name: str, run: Trajectory) -> dict:
        d = run.omega - self.reference.omega
        return {f"omega_{name}_kalman_rad_s": run.omega.tolist(),
                f"mean_speed_{name}_kalman_rad_s": self.mean_speed(run),
                f"max_abs_difference_{name}_kalman_minus_accurate_rad_s": float(np.abs(d).max()),
                f"rms_difference_{name}_kalman_minus_accurate_rad_s": float(np.sqrt(np.mean(d**2)))}

    def table(self) -> str:
        """Plain-text summary."""
        t_end = self.seed.t[-1]
        lines = [f"cam drive at {self.voltage:g} V for {t_end:g} s "
                 f"(follower removed: {self.no_follower_speed:.2f} rad/s)"]
        if self.reference is None:
            failed = self.scheme_failures or {}
            speeds = [f"{name} scheme {self.mean_speed(run):.4f}" + (" (until it stopped)" if name in failed else "")
                      for name, run in (("seed", self.seed), ("corrected", self.corrected))]
            lines.append("mean speed over the last turn [rad/s]: " + ", ".join(speeds))
            lines += [f"{name} scheme stopped: {why}" for name, why in failed.items()]
            for name, c in (self.conditioning or {}).items():
                lines.append(f"{name} scheme conditioning: a relative voltage change of {c['relative_voltage_change']:.0e} "
                             f"moves the speed by up to {c['max_speed_change_rad_s']:.3g} rad/s (condition number "
                             f"{c['condition_number']:.3g})" + (": ILL-CONDITIONED, the impacts in the clearance make "
                                                                "this speed irreproducible" if c["ill_conditioned"]
                                                                else ""))
            lines.append(f"accurate comparison skipped: {self.skipped}")
            return "\n".join(lines)
        d = self.difference
        last = self.reference.t >= self.reference.t[-1] - 1
        lines += [f"mean speed over the last turn [rad/s]: accurate {self.mean_speed(self.reference):.4f}, "
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
            cells = [(self.errors["seed"][i], 17), (self.errors["corrected"][i], 10), (oc[i], 6),
                     (self.errors["seed_vs_limit"][i], 18), (ol[i], 6), (self.angle_errors["seed"][i], 16),
                     (self.angle_errors["corrected"][i], 10)]
            lines.append(f"{h * 1e3:8.4g} " + " ".join(
                f"{x:{w}.2f}" if w == 6 and math.isfinite(x) else
                (f"{x:{w}.4g}" if math.isfinite(x) else f"{'-' if w == 6 else 'failed':>{w}s}")
                for x, w in cells))
        for h, name, why in self.ladder_failures:
            lines.append(f"convergence check, {name} scheme at T = {h * 1e3:.4g} ms stopped: {why}")
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
        if self.reference is not None:
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
            if np.any(np.isfinite(e)):
                ax[1].loglog(self.steps * 1e3, e, "o-", label=labels[k])
        ax[1].set_xlabel("step T [ms]")
        ax[1].set_ylabel(f"max |w - w_ref| in the first {self.window:g} s [rad/s]")
        ax[1].set_title("Discrete scheme error" if self.skipped is None else "Accurate comparison skipped")
        if self.skipped is None:
            ax[1].legend(fontsize="small")
        return ax

    def plot_estimation(self, axes=None, window=None):
        """True, differenced and Kalman-filtered speed and acceleration (2 rows) over
        ``window`` (t0, t1) s (default 0.2 s around a late speed peak); returns the axes."""
        if self.estimation is None:
            raise ValueError("this result has no estimator comparison")
        return self.estimation.plot(axes, window)


def _finite(x) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None
