"""Winding temperature from a two-node thermal network over repeated duty cycles.

Nodes: the winding (capacity C_w) and the housing (C_h); the winding loses heat to the
housing through R_wh, the housing to the ambient through R_ha. The motor's datasheet time
constants are tau_w = R_wh C_w and tau_h = R_ha C_h. With x = (T_w - T_a, T_h - T_a)::

    C_w x_w' = P - (x_w - x_h) / R_wh
    C_h x_h' = (x_w - x_h) / R_wh - x_h / R_ha

The loss is the copper loss P = i^2 R(T_w), R(T) = R_0 (1 + alpha (T - T_0)): linear in
x_w, so the network stays linear over each interval of constant i^2 and one cycle maps x
affinely, x -> Phi x + Gamma. The cycle is cut into equal intervals (the mean of i^2 over
each), each interval is integrated exactly (a matrix exponential), and the steady periodic
state is x* = (I - Phi)^-1 Gamma, reached from a cold start after as many cycles as the
slow time constant asks. A spectral radius of Phi of 1 or more is thermal runaway (the
resistance's rise outgrows the heat path): the temperature has no steady state.
A constant loss P settles at x_w = P (R_wh + R_ha) with the network's two time constants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: intervals of one cycle in the thermal integration
THERMAL_STEPS = 400
#: most cycles of the warm-up trace
MAX_CYCLES = 100_000


@dataclass(frozen=True)
class ThermalNetwork:
    """The two-node network of a motor, SI (temperatures in K).

    Parameters
    ----------
    r_wh, r_ha : float
        Winding-housing and housing-ambient thermal resistances (K/W).
    tau_w, tau_h : float
        Time constants (s).
    ambient : float
        K.
    resistance, resistance_temperature : float
        Winding resistance (ohm) at that temperature (K).
    alpha : float
        Resistance rise per kelvin (1/K).
    """

    r_wh: float
    r_ha: float
    tau_w: float
    tau_h: float
    ambient: float = 298.15
    resistance: float = 1.0
    resistance_temperature: float = 298.15
    alpha: float = 0.0

    @classmethod
    def from_motor(cls, motor) -> "ThermalNetwork | None":
        """The network of a :class:`~servo_toolkit.components.motor.DCMotor`, None when the
        scene gives none."""
        if not motor.has_thermal_network:
            return None
        return cls(motor.thermal_resistance_winding, motor.thermal_resistance_housing,
                   motor.thermal_time_constant_winding, motor.thermal_time_constant_housing,
                   motor.ambient_temperature, motor.resistance, motor.resistance_temperature,
                   motor.copper_temperature_coefficient)

    def augmented(self, i2) -> np.ndarray:
        """The 3x3 matrices [[A, b], [0, 0]] of x' = A x + b for squared currents ``i2``
        (any shape; the result has that shape plus (3, 3))."""
        i2 = np.asarray(i2, dtype=float)
        cw, ch = self.tau_w / self.r_wh, self.tau_h / self.r_ha
        r_amb = self.resistance * (1 + self.alpha * (self.ambient - self.resistance_temperature))
        m = np.zeros(i2.shape + (3, 3))
        m[..., 0, 0] = (i2 * self.resistance * self.alpha - 1 / self.r_wh) / cw
        m[..., 0, 1] = 1 / (self.r_wh * cw)
        m[..., 0, 2] = i2 * r_amb / cw
        m[..., 1, 0] = 1 / (self.r_wh * ch)
        m[..., 1, 1] = -(1 / self.r_wh + 1 / self.r_ha) / ch
        return m

    def step_maps(self, i2, h: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, Gamma) of each interval of length ``h`` with constant ``i2``, exact:
        Phi = exp(A h), Gamma = (integral of exp(A s) over [0, h]) b, by Sylvester's formula
        on the two real eigenvalues of A (the coupling terms are positive, so they are
        distinct); vectorized over ``i2``."""
        m = self.augmented(i2)
        a, b = m[..., :2, :2], m[..., :2, 2]
        half = 0.5 * (a[..., 0, 0] + a[..., 1, 1])
        delta = np.sqrt(0.25 * (a[..., 0, 0] - a[..., 1, 1]) ** 2 + a[..., 0, 1] * a[..., 1, 0])
        l1, l2 = half + delta, half - delta

        def phi1(lam):  # (exp(lam h) - 1) / lam, h at lam = 0
            small = np.abs(lam * h) < 1e-8
            return np.where(small, h * (1 + 0.5 * lam * h), np.expm1(lam * h) / np.where(small, 1.0, lam))

        def apply(f1, f2):  # f(A) from f at the eigenvalues
            c0 = (l1 * f2 - l2 * f1) / (l1 - l2)
            c1 = (f1 - f2) / (l1 - l2)
            return c0[..., None, None] * np.eye(2) + c1[..., None, None] * a

        with np.errstate(over="ignore", invalid="ignore"):  # a runaway overflows: :func:`settles` says so
            phi = apply(np.exp(l1 * h), np.exp(l2 * h))
            gamma = np.einsum("...ij,...j->...i", apply(phi1(l1), phi1(l2)), b)
        return phi, gamma


@dataclass(frozen=True)
class ThermalResult:
    """Winding temperature over repeated cycles.

    Attributes
    ----------
    t_cycle : numpy.ndarray
        Times of the steady periodic cycle (s, interval ends).
    winding, housing : numpy.ndarray
        Their temperatures along that cycle (K); inf when the network runs away.
    cycles : numpy.ndarray
        Cycle numbers of the warm-up trace (from a cold start).
    winding_at_cycle_end : numpy.ndarray
        Winding temperature at the end of each of those cycles (K).
    peak_winding : float
        Highest winding temperature of the steady periodic cycle (K; inf: runaway).
    runaway : bool
        True when no steady state exists.
    """

    t_cycle: np.ndarray
    winding: np.ndarray
    housing: np.ndarray
    cycles: np.ndarray
    winding_at_cycle_end: np.ndarray
    peak_winding: float
    runaway: bool


def interval_i2(current, weight, steps: int = THERMAL_STEPS) -> tuple[np.ndarray, float]:
    """(mean i^2 over each of ``steps`` equal intervals of the cycle, interval length h):
    the samples' i^2 integrated over time and cut at the interval ends. ``current`` may have
    leading axes (a sweep): the intervals are along its last axis."""
    weight = np.asarray(weight, dtype=float)
    keep = weight > 0    # the zero-weight samples of the peaks carry no heat
    current = np.asarray(current, dtype=float)[..., keep]
    weight = weight[keep]
    edges = np.concatenate(([0.0], np.cumsum(weight)))
    total = edges[-1]
    energy = np.concatenate([np.zeros(current.shape[:-1] + (1,)), np.cumsum(current**2 * weight, axis=-1)], axis=-1)
    cut = np.linspace(0.0, total, steps + 1)
    at = np.apply_along_axis(lambda e: np.interp(cut, edges, e), -1, energy)
    h = total / steps
    return np.diff(at, axis=-1) / h, h


def cycle_map(network: ThermalNetwork, i2, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, Gamma) of a whole cycle and the per-interval maps, for ``i2`` of shape
    (..., steps)."""
    phis, gammas = network.step_maps(i2, h)
    phi = np.broadcast_to(np.eye(2), i2.shape[:-1] + (2, 2)).copy()
    gamma = np.zeros(i2.shape[:-1] + (2,))
    with np.errstate(over="ignore", invalid="ignore"):  # a runaway overflows: :func:`settles` says so
        for k in range(i2.shape[-1]):
            phi = phis[..., k, :, :] @ phi
            gamma = np.einsum("...ij,...j->...i", phis[..., k, :, :], gamma) + gammas[..., k, :]
    return phi, gamma, phis, gammas


def settles(phi, gamma) -> np.ndarray:
    """True where the cycle map has a steady periodic state: every eigenvalue of ``Phi``
    inside the unit circle. A map that overflowed (an interval whose winding heats by more
    than e^709 over the coupling: the copper's resistance rise outruns the cooling) has
    none: it runs away."""
    finite = np.all(np.isfinite(phi), axis=(-2, -1)) & np.all(np.isfinite(gamma), axis=-1)
    safe = np.where(finite[..., None, None], phi, 0.0)
    return finite & (np.max(np.abs(np.linalg.eigvals(safe)), axis=-1) < 1 - 1e-12)


def periodic_peak(network: ThermalNetwork, i2, h: float) -> np.ndarray:
    """Highest winding temperature (K) of the steady periodic cycle for each row of ``i2``
    (shape (..., steps)); inf where the network runs away. Vectorized over the rows."""
    phi, gamma, phis, gammas = cycle_map(network, i2, h)
    stable = settles(phi, gamma)
    eye = np.eye(2)
    x = np.linalg.solve(np.where(stable[..., None, None], eye - phi, eye), gamma[..., None])[..., 0]
    peak = x[..., 0].copy()
    for k in range(i2.shape[-1]):
        x = np.einsum("...ij,...j->...i", phis[..., k, :, :], x) + gammas[..., k, :]
        peak = np.maximum(peak, x[..., 0])
    return np.where(stable, network.ambient + peak, np.inf)


def cycle_temperatures(network: ThermalNetwork, current, weight, steps: int = THERMAL_STEPS) -> ThermalResult:
    """The winding and housing temperatures over repeated cycles of the motor ``current``
    (A at samples standing for ``weight`` seconds each)."""
    i2, h = interval_i2(current, weight, steps)
    phi, gamma, phis, gammas = cycle_map(network, i2, h)
    t = h * np.arange(1, steps + 1)
    if not settles(phi, gamma):
        inf = np.full(steps, np.inf)
        return ThermalResult(t, inf, inf, np.zeros(0, int), np.zeros(0), math.inf, True)
    steady = np.linalg.solve(np.eye(2) - phi, gamma)
    trace, x = [], steady
    for k in range(steps):
        x = phis[k] @ x + gammas[k]
        trace.append(x)
    trace = np.array(trace)
    ends, x = [], np.zeros(2)
    tol = 0.01 + 1e-3 * abs(steady[0])
    while len(ends) < MAX_CYCLES:
        x = phi @ x + gamma
        ends.append(x[0])
        if abs(x[0] - steady[0]) <= tol:
            break
    ends = np.asarray(ends)
    return ThermalResult(t, network.ambient + trace[:, 0], network.ambient + trace[:, 1],
                         np.arange(1, ends.size + 1), network.ambient + ends,
                         float(network.ambient + max(trace[:, 0].max(), steady[0])), False)


def step_response(network: ThermalNetwork, power: float, times) -> np.ndarray:
    """Winding temperature (K) at ``times`` (s) from the ambient under a constant loss
    ``power`` (W), the resistance's rise left out (it is the loss itself that is given)."""
    flat = ThermalNetwork(network.r_wh, network.r_ha, network.tau_w, network.tau_h, network.ambient, 1.0,
                          network.ambient, 0.0)
    out = [flat.step_maps(power, t)[1][0] if t > 0 else 0.0  # i^2 R = power with R = 1
           for t in np.atleast_1d(np.asarray(times, dtype=float))]
    return network.ambient + np.asarray(out)


__all__ = ["ThermalNetwork", "ThermalResult", "cycle_temperatures", "periodic_peak", "step_response",
           "interval_i2", "THERMAL_STEPS"]
