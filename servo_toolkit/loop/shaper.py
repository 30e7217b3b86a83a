"""ZV and ZVD input shapers for the drivetrain's lowest mode (command shaping).

An input shaper convolves the command with a few impulses timed on the mode's damped
half period, so that the vibration the first impulse excites is cancelled by the next
(Singer and Seering). With the mode's natural frequency w_n, damping ratio zeta,
``K = exp(-zeta pi / sqrt(1 - zeta^2))`` and the damped half period
``T = pi / (w_n sqrt(1 - zeta^2))``:

- ZV: amplitudes ``[1, K] / (1 + K)`` at ``[0, T]``; delay T.
- ZVD: amplitudes ``[1, 2K, K^2] / (1 + K)^2`` at ``[0, T, 2T]``; delay 2T, less
  sensitive to an error in the mode's frequency.

The shaper delays the command by its duration (stated as :attr:`InputShaper.delay`); it sits
before the loop and the feedforward, outside the loop, and changes no margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SHAPER_KINDS = ("zv", "zvd")


@dataclass(frozen=True)
class InputShaper:
    """Impulses of an input shaper.

    Parameters
    ----------
    kind : {"zv", "zvd"}
    frequency : float
        Natural frequency of the shaped mode (Hz).
    damping_ratio : float
        Damping ratio of the mode.
    times : tuple of float
        Impulse times (s), from 0.
    amplitudes : tuple of float
        Impulse amplitudes, summing to 1.
    """

    kind: str
    frequency: float
    damping_ratio: float
    times: tuple
    amplitudes: tuple

    @property
    def delay(self) -> float:
        """The command's delay through the shaper (s): its last impulse time."""
        return float(self.times[-1])

    @classmethod
    def design(cls, kind: str, frequency: float, damping_ratio: float = 0.0) -> "InputShaper":
        """The ``kind`` shaper of a mode at ``frequency`` (Hz) with ``damping_ratio``."""
        if kind not in SHAPER_KINDS:
            raise ValueError(f"shaper kind must be one of {SHAPER_KINDS}, got {kind!r}")
        if not (frequency > 0 and math.isfinite(frequency)):
            raise ValueError(f"shaper frequency must be positive and finite, got {frequency!r}")
        if not 0 <= damping_ratio < 1:
            raise ValueError(f"shaper damping_ratio must be in [0, 1), got {damping_ratio!r}")
        root = math.sqrt(1.0 - damping_ratio**2)
        k = math.exp(-damping_ratio * math.pi / root)
        half = math.pi / (2 * math.pi * frequency * root)
        if kind == "zv":
            amps, times = np.array([1.0, k]) / (1 + k), (0.0, half)
        else:
            amps, times = np.array([1.0, 2 * k, k * k]) / (1 + k) ** 2, (0.0, half, 2 * half)
        return cls(kind, float(frequency), float(damping_ratio), tuple(times), tuple(float(a) for a in amps))

    def shape(self, t, command):
        """The shaped command at times ``t`` of a callable ``command(t)`` (0 before t = 0 is
        the command's own value at its argument)."""
        t = np.asarray(t, dtype=float)
        return sum(a * np.asarray(command(t - ti), dtype=float) for a, ti in zip(self.amplitudes, self.times))

    def residual_vibration(self, frequency: float, damping_ratio: float | None = None) -> float:
        """Residual vibration of a mode at ``frequency`` (Hz) after the shaped impulse,
        relative to the unshaped one (the theory's percentage vibration; 0 at the design
        frequency)."""
        z = self.damping_ratio if damping_ratio is None else damping_ratio
        wn = 2 * math.pi * frequency
        wd = wn * math.sqrt(1 - z * z)
        tn = self.times[-1]
        c = sum(a * math.exp(z * wn * ti) * math.cos(wd * ti) for a, ti in zip(self.amplitudes, self.times))
        s = sum(a * math.exp(z * wn * ti) * math.sin(wd * ti) for a, ti in zip(self.amplitudes, self.times))
        return float(math.exp(-z * wn * tn) * math.hypot(c, s))

    def describe(self) -> str:
        """One line: kind, mode and delay."""
        return (f"{self.kind.upper()} shaper on {self.frequency:.4g} Hz (zeta {self.damping_ratio:.3g}), "
                f"delay {self.delay * 1e3:.3g} ms")

    def to_dict(self) -> dict:
        """JSON-ready fields."""
        return {"kind": self.kind, "frequency_hz": self.frequency, "damping_ratio": self.damping_ratio,
                "times_s": list(self.times), "amplitudes": list(self.amplitudes), "delay_s": self.delay}


def shaper_for(scene, kind: str = "zv", damping_ratio: float = 0.05, q0: float | None = None) -> InputShaper:
    """The ``kind`` shaper on the drivetrain's lowest mode at ``q0`` (default mid-stroke):
    the two-mass reduction's resonance sqrt(K (J1 + J2) / (J1 J2)).

    Raises
    ------
    SceneError
        A rigid drivetrain has no mode to shape (key ``drivetrain``).
    """
    from ..errors import SceneError
    drive = scene.drivetrain
    q = drive.mid_stroke if q0 is None else q0
    j1, j2, k = drive.chain.modal_two_mass(q)
    if not (math.isfinite(k) and j2 > 0):
        raise SceneError("drivetrain", "has no compliance: there is no mode to shape (got a rigid chain)")
    wr = math.sqrt(k * (j1 + j2) / (j1 * j2))
    return InputShaper.design(kind, wr / (2 * math.pi), damping_ratio)


__all__ = ["InputShaper", "SHAPER_KINDS", "shaper_for"]
