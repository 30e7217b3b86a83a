"""Rating life L10 of a ball screw (ISO 3408-5) and of its axial bearing (ISO 281) from the
load spectrum of a duty cycle.

The equivalent (cubic mean) load over the revolutions turned at each load is

    F_m = (sum |F_i|^p n_i / sum n_i)^(1/p)

with n_i the revolutions at load F_i (here each sample's |screw speed| * its time / 2 pi),
and the rating life in revolutions is L10 = (C / F_m)^p * 10^6: p = 3 for the screw and a
ball bearing, 10/3 for a roller bearing; 90 % reliability (a1 = 1), no modification factors.
The bearing is the screw's axial support: it carries the screw thrust (P = F_a).
Hours follow from the revolutions the screw turns per cycle, the cycle repeated back to back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: life exponents
BALL, ROLLER = 3.0, 10.0 / 3.0


@dataclass(frozen=True)
class Life:
    """Rating life of one part.

    Attributes
    ----------
    part : str
    rating : float
        Dynamic load rating C (N).
    equivalent_load : float
        F_m (N).
    revolutions : float
        L10 (revolutions; inf without load).
    hours : float
        L10 in hours of the duty cycle (inf without motion or load).
    """

    part: str
    rating: float
    equivalent_load: float
    revolutions: float
    hours: float

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {"part": self.part, "rating_N": self.rating, "equivalent_load_N": self.equivalent_load,
                "L10_revolutions": _finite(self.revolutions), "L10_hours": _finite(self.hours)}


def _finite(x: float):
    return x if math.isfinite(x) else None


def equivalent_load(forces, revolutions, exponent: float = BALL) -> float:
    """Cubic (p-th power) mean load F_m over ``revolutions`` turned at each of ``forces``."""
    n = np.abs(np.asarray(revolutions, dtype=float))
    if not n.sum() > 0:
        return 0.0
    return float((np.sum(np.abs(np.asarray(forces, dtype=float)) ** exponent * n) / n.sum()) ** (1 / exponent))


def rating_life(rating: float, load: float, exponent: float = BALL) -> float:
    """L10 in revolutions: (C / F)^p 10^6 (inf for no load)."""
    return math.inf if load <= 0 else (rating / load) ** exponent * 1e6


def part_life(part: str, rating: float, forces, revolutions, cycle_duration: float, exponent: float = BALL) -> Life:
    """The :class:`Life` of a part with ``rating`` under the spectrum (``forces``,
    ``revolutions`` per cycle)."""
    fm = equivalent_load(forces, revolutions, exponent)
    revs = rating_life(rating, fm, exponent)
    per_hour = float(np.abs(revolutions).sum()) * 3600.0 / cycle_duration
    hours = math.inf if per_hour == 0 else revs / per_hour
    return Life(part, rating, fm, revs, hours)


def screw_lives(stage, thrust, screw_speed, weight, cycle_duration: float) -> list:
    """The lives of a ball-screw stage's screw and bearing that the scene rates."""
    revs = np.abs(screw_speed) * weight / (2 * math.pi)
    out = []
    if stage.dynamic_load_rating is not None:
        out.append(part_life(f"{stage.name} (screw)", stage.dynamic_load_rating, thrust, revs, cycle_duration))
    if stage.bearing_dynamic_load_rating is not None:
        p = ROLLER if stage.bearing_kind == "roller" else BALL
        out.append(part_life(f"{stage.name} (bearing)", stage.bearing_dynamic_load_rating, thrust, revs,
                             cycle_duration, p))
    return out


__all__ = ["Life", "equivalent_load", "rating_life", "part_life", "screw_lives", "BALL", "ROLLER"]
