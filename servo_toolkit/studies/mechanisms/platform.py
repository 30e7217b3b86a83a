"""The crossed-arch platform's ramp study (seed 003): both axes driven at constant rates,
motor torques from the Lagrange dynamics with external moments."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...components.platform.model import PlatformModel


@dataclass(frozen=True)
class PlatformRampResult:
    """Motor torques along a constant-rate ramp for several external load cases.

    Attributes
    ----------
    t : numpy.ndarray
        Time (s).
    q, qd : numpy.ndarray
        (alpha, beta) (rad) and their rates (rad/s), shape (2, n).
    load_moments : numpy.ndarray
        (Mx, My) per case (N*m), shape (n_cases, 2).
    torques : numpy.ndarray
        (tau1, tau2) per case (N*m), shape (n_cases, 2, n).
    motor_power, kinetic_power, load_power : numpy.ndarray
        tau . theta', dT/dt (finite differences of T along the run) and M_load . q' (W),
        shape (n_cases, n) for the powers that depend on the case.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    load_moments: np.ndarray
    torques: np.ndarray
    motor_power: np.ndarray
    kinetic_power: np.ndarray
    load_power: np.ndarray

    @property
    def power_residual(self) -> np.ndarray:
        """Relative virtual-power imbalance per case (interior samples)."""
        res = self.motor_power - self.kinetic_power - self.load_power
        scale = np.abs(self.motor_power).max(axis=1, keepdims=True) + 1e-300
        return np.abs(res[:, 1:-1]).max(axis=1) / scale[:, 0]

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {
            "study": "ramp", "t_s": self.t.tolist(),
            "alpha_deg": np.degrees(self.q[0]).tolist(), "beta_deg": np.degrees(self.q[1]).tolist(),
            "cases": [{"load_moments_Nm": m.tolist(), "tau1_Nm": tau[0].tolist(), "tau2_Nm": tau[1].tolist(),
                       "tau1_range_Nm": [float(tau[0].min()), float(tau[0].max())],
                       "tau2_range_Nm": [float(tau[1].min()), float(tau[1].max())],
                       "power_balance_relative_residual": float(r)}
                      for m, tau, r in zip(self.load_moments, self.torques, self.power_residual)],
        }

    def table(self) -> str:
        """Plain-text summary."""
        lines = [f"ramp: alpha to {math.degrees(self.q[0, -1]):.1f} deg, beta to {math.degrees(self.q[1, -1]):.1f} deg "
                 f"in {self.t[-1]:g} s",
                 f"{'Mx [N*m]':>9s} {'My [N*m]':>9s} {'tau1 min..max [N*m]':>24s} {'tau2 min..max [N*m]':>24s} "
                 f"{'power residual':>15s}"]
        for m, tau, r in zip(self.load_moments, self.torques, self.power_residual):
            lines.append(f"{m[0]:9.3g} {m[1]:9.3g} {tau[0].min():11.5g}..{tau[0].max():<11.5g} "
                         f"{tau[1].min():11.5g}..{tau[1].max():<11.5g} {r:15.2e}")
        return "\n".join(lines)

    def plot(self, ax=None):
        """Motor torques against time per case; returns the axes."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(1, 2, figsize=(10, 3.5))
        for m, tau in zip(self.load_moments, self.torques):
            label = f"Mx {m[0]:g}, My {m[1]:g} N*m"
            ax[0].plot(self.t, tau[0], label=label)
            ax[1].plot(self.t, tau[1], label=label)
        for a, name in zip(ax, ("motor 1 (alpha)", "motor 2 (beta)")):
            a.set_xlabel("time [s]")
            a.set_ylabel("torque [N*m]")
            a.set_title(name)
        ax[1].legend(fontsize="small")
        return ax


#: a torque below this fraction of the largest torque of the study is rounding, printed as 0
ROUNDING = 1e-12


def without_rounding(torques: np.ndarray) -> np.ndarray:
    """``torques`` with every entry below ``ROUNDING`` times the largest magnitude among
    them set to exactly 0 (a term that cancels to 1e-23 N*m means 0, not a torque)."""
    torques = np.asarray(torques, float)
    scale = float(np.max(np.abs(torques))) if torques.size else 0.0
    return np.where(np.abs(torques) <= ROUNDING * scale, 0.0, torques)


def ramp(model: PlatformModel, rate_alpha: float, rate_beta: float, duration: float, load_moments,
         samples: int = 401) -> PlatformRampResult:
    """Inverse dynamics along alpha = rate_alpha t, beta = rate_beta t for each load case.

    Torques that are rounding of terms cancelling (below ``ROUNDING`` times the largest
    torque of the study) are exactly 0."""
    t = np.linspace(0.0, duration, samples)
    q = np.array([rate_alpha * t, rate_beta * t])
    qd = np.array([np.full_like(t, rate_alpha), np.full_like(t, rate_beta)])
    qdd = np.zeros_like(q)
    loads = np.asarray(load_moments, dtype=float).reshape(-1, 2)
    theta_dot = np.einsum("ij...,j...->i...", model.jacobian(q[0], q[1]), qd)
    kinetic = model.kinetic_energy(q[0], q[1], qd[0], qd[1])
    kinetic_power = np.gradient(kinetic, t, edge_order=2)
    torques = without_rounding([model.motor_torques(q, qd, qdd, m[:, None]) for m in loads])
    motor_power = [np.sum(tau * theta_dot, axis=0) for tau in torques]
    load_power = [m @ qd for m in loads]
    n = len(loads)
    return PlatformRampResult(t, q, qd, loads, torques, np.array(motor_power),
                              np.broadcast_to(kinetic_power, (n, t.size)).copy(), np.array(load_power))
