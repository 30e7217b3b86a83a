"""Rating life L10 of a ball screw (ISO 3408-5) and of its axial bearing (ISO 281) from the
load spectrum of a duty cycle.

The equivalent (cubic mean) load over the revolutions turned at each load is

    F_m = (sum |F_i|^p n_i / sum n_i)^(1/p)

with n_i the revolutions at load F_i (here each sample's |screw speed| * its time / 2 pi),
and the rating life in revolutions is L10 = (C / F_m)^p * 10^6: p = 3 for the screw and a
ball bearing, 10/3 for a roller bearing; 90 % reliability (a1 = 1), no modification factors.
Hours follow from the revolutions the screw turns per cycle, the cycle repeated back to back.

The screw's nut is a single nut with backlash: a thrust in each direction loads the other
flank of its thread, so (ISO 3408-5, a nut with backlash loaded in both directions) each
direction k has its own equivalent load F_m,k over all the revolutions of the cycle (those
turned under the other direction's thrust count with zero load) and its own life L_k, and
the nut's life is the weakest-link combination of the two,

    L = (L+^(-10/9) + L-^(-10/9))^(-9/10)

(10/9: the Weibull slope of ball and roller raceways). A thrust in one direction only gives
the single F_m; thrusts in both directions give at most 2^(1/10) = 7.2 % more life than
lumping them into one F_m. The bearing is the screw's axial support, rated as one part for
the thrust in both directions (P = |F_a|, the lumped F_m: conservative by the same at most
7.2 % for a pair of bearings that each carry one direction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: life exponents
BALL, ROLLER = 3.0, 10.0 / 3.0
#: Weibull slope of a raceway's life: the exponent that combines the lives of two raceways
WEIBULL_SLOPE = 10.0 / 9.0


@dataclass(frozen=True)
class Life:
    """Rating life of one part.

    Attributes
    ----------
    part : str
    rating : float
        Dynamic load rating C (N).
    equivalent_load : float
        F_m (N): the constant load of the same life (for a nut loaded in both directions,
        C (L / 10^6)^(-1/p) of the combined life L).
    revolutions : float
        L10 (revolutions; inf without load).
    hours : float
        L10 in hours of the duty cycle (inf without motion or load).
    direction_loads : tuple of float or None
        (F_m,+, F_m,-) of a nut loaded in both directions (N; module docstring), None for a
        part rated on the lumped spectrum.
    """

    part: str
    rating: float
    equivalent_load: float
    revolutions: float
    hours: float
    direction_loads: tuple | None = None

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        out = {"part": self.part, "rating_N": self.rating, "equivalent_load_N": self.equivalent_load,
               "L10_revolutions": _finite(self.revolutions), "L10_hours": _finite(self.hours)}
        if self.direction_loads is not None:
            out["equivalent_load_by_direction_N"] = list(self.direction_loads)
        return out


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


def combined_life(lives, slope: float = WEIBULL_SLOPE) -> float:
    """Life of parts that fail as a weakest link: (sum L_k^(-e))^(-1/e) (inf lives drop out)."""
    terms = [life ** -slope for life in lives if math.isfinite(life)]
    return math.inf if not terms else sum(terms) ** (-1 / slope)


def nut_life(part: str, rating: float, forces, revolutions, cycle_duration: float, exponent: float = BALL) -> Life:
    """The :class:`Life` of a single nut with backlash under thrust in both directions: each
    direction's F_m and life, combined (module docstring)."""
    forces = np.asarray(forces, dtype=float)
    revolutions = np.abs(np.asarray(revolutions, dtype=float))
    loads = tuple(equivalent_load(np.where(sign * forces > 0, forces, 0.0), revolutions, exponent)
                  for sign in (1, -1))
    revs = combined_life([rating_life(rating, f, exponent) for f in loads])
    per_hour = float(revolutions.sum()) * 3600.0 / cycle_duration
    hours = math.inf if per_hour == 0 else revs / per_hour
    fm = 0.0 if not math.isfinite(revs) else rating * (revs / 1e6) ** (-1 / exponent)
    return Life(part, rating, fm, revs, hours, loads)


def screw_lives(stage, thrust, screw_speed, weight, cycle_duration: float) -> list:
    """The lives of a screw stage's nut (both directions, :func:`nut_life`) and of its
    bearing (the lumped spectrum) that the scene rates."""
    revs = np.abs(screw_speed) * weight / (2 * math.pi)
    out = []
    if stage.dynamic_load_rating is not None:
        out.append(nut_life(f"{stage.name} (screw)", stage.dynamic_load_rating, thrust, revs, cycle_duration))
    if stage.bearing_dynamic_load_rating is not None:
        p = ROLLER if stage.bearing_kind == "roller" else BALL
        out.append(part_life(f"{stage.name} (bearing)", stage.bearing_dynamic_load_rating, thrust, revs,
                             cycle_duration, p))
    return out


__all__ = ["Life", "equivalent_load", "rating_life", "part_life", "nut_life", "combined_life", "screw_lives",
           "BALL", "ROLLER", "WEIBULL_SLOPE"]
