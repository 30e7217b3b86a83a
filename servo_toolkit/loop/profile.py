"""Jerk-limited moves: a distance within speed, acceleration and jerk limits as an S-curve.

The seven-segment profile (jerk +j, constant acceleration, jerk -j, constant speed, then the
mirror image of the acceleration) with jerk time ``Tj``, constant-acceleration time ``Ta``
and constant-speed time ``Tv``::

    Tj = a_max / j_max,  Ta = v_max / a_max - Tj          (both limits reached)
    Tj = sqrt(v_max / j_max), Ta = 0                      (v_max * j_max < a_max^2: the
                                                           acceleration stays below a_max)
    Tv = D / v_p - (2 Tj + Ta),  v_p = j Tj (Tj + Ta)     (cruise at v_p)

A distance too short to reach the cruise speed has Tv = 0 and the largest acceleration phase
that fits: with the acceleration limit reached, ``D = a_max (Tj + Ta) (2 Tj + Ta)``, so
``Ta = (sqrt(Tj^2 + 4 D / a_max) - 3 Tj) / 2``; when even that is negative, Ta = 0 and
``Tj = (D / (2 j_max))^(1/3)``. The duration is ``T = 4 Tj + 2 Ta + Tv``. Position, speed and
acceleration are analytic (the kernel evaluates the same formulas,
``move_rates`` in ``servo_toolkit/_physics/command.h``); r, r' and r'' are continuous and the jerk
is bounded by j_max.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError


def _positive(key: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(key, f"must be a number (got {value!r})")
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise SceneError(key, f"must be positive and finite (got {value:g})")
    return value


@dataclass(frozen=True)
class MoveProfile:
    """A jerk-limited move of ``distance`` (rad, or m for an output travel; signed).

    Parameters
    ----------
    distance : float
        Signed distance of the move (nonzero).
    v_max, a_max, j_max : float
        Speed, acceleration and jerk limits (rad/s, rad/s^2, rad/s^3; m/s... for a travel).

    Attributes
    ----------
    jerk_time, acceleration_time, cruise_time : float
        ``Tj``, ``Ta``, ``Tv`` (s), see the module docstring.
    """

    distance: float
    v_max: float
    a_max: float
    j_max: float

    def __post_init__(self):
        d = self.distance
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not math.isfinite(d) or d == 0:
            raise SceneError("move.distance", f"must be a nonzero finite number (got {d!r})")
        for name in ("v_max", "a_max", "j_max"):
            object.__setattr__(self, name, _positive(f"move.{name}", getattr(self, name)))
        object.__setattr__(self, "distance", float(d))

    @property
    def _times(self):
        dist, v, a, j = abs(self.distance), self.v_max, self.a_max, self.j_max
        if v * j < a * a:  # the acceleration limit is not reached at full speed
            tj, ta = math.sqrt(v / j), 0.0
        else:
            tj, ta = a / j, v / a - a / j
        vp = j * tj * (tj + ta)
        if dist >= vp * (2 * tj + ta):
            return tj, ta, dist / vp - (2 * tj + ta)
        if ta > 0:  # a_max still reached: the constant-acceleration time that fits
            ta = 0.5 * (math.sqrt(tj * tj + 4 * dist / a) - 3 * tj)
        if ta <= 0:  # a_max not reached: two jerk phases each way
            tj, ta = (dist / (2 * j)) ** (1 / 3), 0.0
        return tj, ta, 0.0

    @property
    def jerk_time(self) -> float:
        return self._times[0]

    @property
    def acceleration_time(self) -> float:
        return self._times[1]

    @property
    def cruise_time(self) -> float:
        return self._times[2]

    @property
    def duration(self) -> float:
        """T = 4 Tj + 2 Ta + Tv (s)."""
        tj, ta, tv = self._times
        return 4 * tj + 2 * ta + tv

    @property
    def peak_speed(self) -> float:
        """The cruise speed reached, j Tj (Tj + Ta) (unsigned)."""
        tj, ta, _ = self._times
        return self.j_max * tj * (tj + ta)

    @property
    def peak_acceleration(self) -> float:
        """The acceleration reached, j Tj (unsigned)."""
        return self.j_max * self._times[0]

    def block(self) -> np.ndarray:
        """The kernel's block: [signed jerk, Tj, Ta, Tv]."""
        tj, ta, tv = self._times
        return np.array([math.copysign(self.j_max, self.distance), tj, ta, tv])

    def rates(self, t) -> tuple:
        """Position (from 0), speed and acceleration at times ``t`` (s from the start):
        ``(r, r', r'')`` as arrays."""
        j, tj, ta, tv = self.block()
        t = np.asarray(t, dtype=float)
        t3 = 2 * tj + ta
        a, total = j * tj, 2 * t3 + tv
        vp = a * (tj + ta)
        p3 = 0.5 * vp * t3
        u = np.clip(t, 0.0, total)
        back = u > t3 + tv
        u = np.where(back, total - u, u)
        w2 = u - tj
        w3 = t3 - u
        conds = [u <= tj, u <= tj + ta, u <= t3]
        p = np.select(conds, [j * u**3 / 6, j * tj**3 / 6 + 0.5 * j * tj**2 * w2 + 0.5 * a * w2**2,
                              p3 - vp * w3 + j * w3**3 / 6], p3 + vp * (u - t3))
        v = np.select(conds, [0.5 * j * u**2, 0.5 * j * tj**2 + a * w2, vp - 0.5 * j * w3**2], vp)
        acc = np.select(conds, [j * u, a, j * w3], 0.0)
        p = np.where(back, 2 * p3 + vp * tv - p, p)
        acc = np.where(back, -acc, acc)
        return p, v, acc

    def describe(self, output_unit: str = "rad") -> str:
        """One line in engineering units (deg or mm)."""
        scale, unit = (1e3, "mm") if output_unit == "m" else (180 / math.pi, "deg")
        return (f"move {self.distance * scale:.4g} {unit} in {self.duration:.4g} s (v {self.peak_speed * scale:.4g} "
                f"{unit}/s, a {self.peak_acceleration * scale:.4g} {unit}/s^2, jerk {self.j_max * scale:.4g} {unit}/s^3)")

    def to_dict(self) -> dict:
        """JSON-ready fields (SI)."""
        tj, ta, tv = self._times
        return {"distance": self.distance, "v_max": self.v_max, "a_max": self.a_max, "j_max": self.j_max,
                "jerk_time_s": tj, "acceleration_time_s": ta, "cruise_time_s": tv, "duration_s": self.duration,
                "peak_speed": self.peak_speed, "peak_acceleration": self.peak_acceleration}


__all__ = ["MoveProfile"]
