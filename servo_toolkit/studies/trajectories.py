"""Prescribed motions of the generalized coordinate q for inverse-dynamics studies."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SineMotion:
    """q(t) = offset + amplitude * sin(2*pi*frequency*t + phase).

    Parameters
    ----------
    amplitude : float
        rad (of q).
    frequency : float
        Hz.
    offset : float
        rad, the centre of the motion.
    phase : float
        rad at t = 0.

    Examples
    --------
    Seed 000's full-stroke signal (+30, 0, -30, 0 deg in 0.6 s, extremes at 0.15 s and 0.45 s):

    >>> m = SineMotion(math.radians(30), 1 / 0.6)
    >>> round(math.degrees(float(m.position(0.15))), 9), round(math.degrees(float(m.position(0.45))), 9)
    (30.0, -30.0)
    """

    amplitude: float
    frequency: float
    offset: float = 0.0
    phase: float = 0.0

    @property
    def period(self) -> float:
        """1 / frequency (s)."""
        return 1.0 / self.frequency

    @property
    def omega(self) -> float:
        """Angular frequency (rad/s)."""
        return 2 * math.pi * self.frequency

    def position(self, t) -> np.ndarray:
        """q(t) (rad)."""
        return self.offset + self.amplitude * np.sin(self.omega * np.asarray(t, dtype=float) + self.phase)

    def speed(self, t) -> np.ndarray:
        """dq/dt (rad/s)."""
        return self.amplitude * self.omega * np.cos(self.omega * np.asarray(t, dtype=float) + self.phase)

    def acceleration(self, t) -> np.ndarray:
        """d2q/dt2 (rad/s^2)."""
        return -self.amplitude * self.omega**2 * np.sin(self.omega * np.asarray(t, dtype=float) + self.phase)

    def __call__(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, qd, qdd) at times t."""
        return self.position(t), self.speed(t), self.acceleration(t)

    def times(self, samples_per_period: int = 2000, periods: float = 1.0) -> np.ndarray:
        """Sample times over ``periods`` periods, both ends included; a multiple of 4 samples
        per period lands on the extremes and zero crossings exactly."""
        n = int(round(samples_per_period * periods))
        return np.linspace(0.0, periods * self.period, n + 1)

    def describe(self, unit=None) -> str:
        """One-line description in the output's unit (an
        :class:`~servo_toolkit.core.output_units.OutputUnit`; default degrees) and Hz."""
        if unit is None:
            from ..core.output_units import OutputUnit
            unit = OutputUnit()
        return (f"sine {unit.text(self.amplitude)} about {unit.text(self.offset)}, "
                f"{self.frequency:.4g} Hz (period {self.period:.4g} s)")
