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
from dataclasses import dataclass, replace

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
    mode : str
        Which mode it was designed on (:func:`drivetrain_modes`; "" when given by hand).
    """

    kind: str
    frequency: float
    damping_ratio: float
    times: tuple
    amplitudes: tuple
    mode: str = ""

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
        on = f"{self.mode.replace('_', '-')} mode " if self.mode else ""
        return (f"{self.kind.upper()} shaper on the {on}{self.frequency:.4g} Hz (zeta {self.damping_ratio:.3g}), "
                f"delay {self.delay * 1e3:.3g} ms")

    def to_dict(self) -> dict:
        """JSON-ready fields."""
        return {"kind": self.kind, "frequency_hz": self.frequency, "damping_ratio": self.damping_ratio,
                "times_s": list(self.times), "amplitudes": list(self.amplitudes), "delay_s": self.delay,
                "mode": self.mode}

    @classmethod
    def from_dict(cls, data: dict) -> "InputShaper":
        """A shaper from :meth:`to_dict`'s fields (redesigned from kind, frequency and damping,
        so its impulses are the theory's)."""
        return replace(cls.design(str(data["kind"]), float(data["frequency_hz"]), float(data["damping_ratio"])),
                       mode=str(data.get("mode", "")))


#: the modes a shaper may be designed on
SHAPER_MODES = ("auto", "closed_loop", "free", "locked")


def drivetrain_modes(scene, controller=None, q0: float | None = None,
                     structural_damping: float | None = None) -> dict:
    """The drivetrain's mode three ways at ``q0`` (default: the design's operating point),
    each ``(frequency Hz, damping ratio)``:

    - ``"free"``: the two-mass reduction's free-free mode sqrt(K (J1 + J2) / (J1 J2)), with
      the plant's structural damping: what an unpowered (or torque-driven) drive rings at;
    - ``"locked"``: the load against a held motor, sqrt(K / J2) (the antiresonance): the limit
      of a speed loop much stiffer than the mode;
    - ``"closed_loop"`` (with a controller): the least damped pole pair of the linear closed
      loop between half the locked and twice the free frequency: the mode as the controller
      shapes it, which is what a command through the loop excites.

    Raises
    ------
    SceneError
        A rigid drivetrain has no mode to shape (key ``drivetrain``).
    """
    from ..errors import SceneError
    from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, plant_parameters
    from ..drivetrain.operating_point import operating_point
    zeta = DEFAULT_STRUCTURAL_DAMPING if structural_damping is None else float(structural_damping)
    q0, _ = operating_point(scene, q0)
    p = plant_parameters(scene, q0, "auto", zeta)
    if p.rigid:
        raise SceneError("drivetrain", "has no compliance: there is no mode to shape (got a rigid chain)")
    out = {"free": (p.resonance_hz, zeta), "locked": (p.antiresonance_hz, zeta * math.sqrt(p.J1 / (p.J1 + p.J2)))}
    if controller is not None:
        from .closed_loop import closed_loop_block
        poles = closed_loop_block(scene, replace(controller, schedule=None, shaper=None, feedforward=None), q0,
                                  "auto", zeta).poles()
        wn = np.abs(poles)
        band = ((poles.imag > 0) & (wn >= 2 * math.pi * 0.5 * p.antiresonance_hz)
                & (wn <= 2 * math.pi * 2.0 * p.resonance_hz))
        if np.any(band):
            z = -poles.real / np.where(wn > 0, wn, 1.0)
            k = int(np.argmin(np.where(band, z, np.inf)))
            out["closed_loop"] = (float(wn[k] / (2 * math.pi)), float(max(z[k], 0.0)))
    return out


def shaper_for(scene, kind: str = "zv", damping_ratio: float | None = None, q0: float | None = None,
               controller=None, mode: str = "auto") -> InputShaper:
    """The ``kind`` shaper on the drivetrain's mode at ``q0`` (:func:`drivetrain_modes`).

    Parameters
    ----------
    scene : Scene
    kind : {"zv", "zvd"}
    damping_ratio : float, optional
        Replaces the mode's damping ratio (default: the model's).
    q0 : float, optional
    controller : CascadeController, optional
        The loop the command goes through (for the closed-loop mode).
    mode : {"auto", "closed_loop", "free", "locked"}
        ``"auto"``: the closed-loop mode when a controller is given (and found), else the
        free-free mode.

    Raises
    ------
    SceneError
        A rigid drivetrain (key ``drivetrain``); an unknown mode, or the closed-loop mode
        without a controller (key ``shaper``).
    """
    from ..errors import SceneError
    if mode not in SHAPER_MODES:
        raise SceneError("shaper", f"mode must be one of {', '.join(SHAPER_MODES)} (got {mode!r})")
    modes = drivetrain_modes(scene, controller, q0)
    if mode == "auto":
        mode = "closed_loop" if "closed_loop" in modes else "free"
    if mode not in modes:
        raise SceneError("shaper", "the closed-loop mode needs the controller (and a lightly damped pole pair "
                                   "near the drivetrain mode)")
    f, zeta = modes[mode]
    return replace(InputShaper.design(kind, f, zeta if damping_ratio is None else damping_ratio), mode=mode)


__all__ = ["InputShaper", "SHAPER_KINDS", "SHAPER_MODES", "drivetrain_modes", "shaper_for"]
