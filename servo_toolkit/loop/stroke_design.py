"""Design points along the stroke: the plants a nominal design search must hold together.

Why (physics)
-------------
Along a linkage's stroke the kinematic ratio N(q) changes, and with it every quantity the
loop sees: the motor-side inertia J1(q) (rotor and gears reflected with N^2), the series
stiffness K(q) (each stage's k times its ratio to the output squared, seed 001 eq 8) and so
the drivetrain mode sqrt(K (1/J1 + 1/J2)) and its anti-resonance sqrt(K / J2). On the
reference EMA (rocker, +-30 deg) the anti-resonance walks from 29.3 Hz at 0 deg down to
25.9 Hz at -30 deg. A notch tuned at q0 then leaves the moved, lightly damped mode
unfiltered at the end of the stroke: the loop stays stable but with almost no gain margin.

What the search does
--------------------
It evaluates every candidate controller on the plants linearized at a few design points
(:func:`design_points`: q0, the stroke ends, the largest and smallest motor-side inertia,
the lowest and highest drivetrain anti-resonance), with the same closed-form responses as
the stroke check (:class:`.stroke.StrokeLoops`: each point's N, J1, J2, K, damping and
torque gain; the controller's speed feedback keeps the design ratio N(q0)). Margins (gain
margin, phase margin, sensitivity peak) count at their worst over the points; bandwidth and
phase lag are judged at q0, the operating point the requirement is stated for (the worst
bandwidth over the stroke stays in the stroke check's summary). Resonance-filter candidates
include a notch centred on the anti-resonance's walk and widened to cover it, and a
low-pass below its lowest value (:func:`stroke_filters`).
"""

from __future__ import annotations

import math

import numpy as np

from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, plant_parameters
from .response import plant_responses
from .stroke import INERTIA_SPREAD_LIMIT, STROKE_POINTS, stroke_points
from .stroke_plants import PlantScan, plants_at

MAX_DESIGN_POINTS = 7
"""At most this many design points (q0 first)."""
WALK_LIMIT = 1.02
"""Highest / lowest anti-resonance over the design points above which the stroke-wide
filters join the candidates."""


def design_points(scene, q0: float, model: str = "auto", structural_damping: float = DEFAULT_STRUCTURAL_DAMPING,
                  scan_points: int = STROKE_POINTS, scan: PlantScan | None = None):
    """The stroke points a nominal design is evaluated on, q0 first.

    Parameters
    ----------
    scene : Scene
    q0 : float
        Operating point (rad).
    model : {"auto", "two_mass", "rigid"}
    structural_damping : float
    scan_points : int
        Evenly spaced points (those of the stroke check) scanned for the extremes.
    scan : PlantScan, optional
        The plants at those points when the caller has them (:func:`.stroke.plant_scan`).

    Returns
    -------
    q : numpy.ndarray
        Design points (rad): q0, the stroke ends, the largest and smallest motor-side
        inertia, the lowest and highest anti-resonance (duplicates removed; at most
        :data:`MAX_DESIGN_POINTS`).
    params : tuple of PlantParameters
        The plant at each point.
    """
    drive = scene.drivetrain
    grid = stroke_points(drive, scan_points, extra=[q0])
    params = plants_at(scene, grid, model, structural_damping, scan)
    motor = drive.motor_inertia(grid)
    fa = np.array([p.antiresonance_hz if not p.rigid else np.inf for p in params])
    picks = [int(np.argmin(np.abs(grid - q0))), 0, grid.size - 1, int(np.argmax(motor)), int(np.argmin(motor))]
    if np.any(np.isfinite(fa)):
        picks += [int(np.argmin(fa)), int(np.argmax(np.where(np.isfinite(fa), fa, -np.inf)))]
    keep = list(dict.fromkeys(picks))[:MAX_DESIGN_POINTS]
    q = grid[keep]
    q[0] = q0
    first = params[keep[0]] if grid[keep[0]] == q0 else plant_parameters(scene, q0, model, structural_damping)
    ps = [first] + [params[k] for k in keep[1:]]
    return q, tuple(ps)


def antiresonance_range(params) -> tuple[float, float] | None:
    """(lowest, highest) drivetrain anti-resonance (Hz) over ``params``; None if rigid."""
    fa = [p.antiresonance_hz for p in params if not p.rigid and math.isfinite(p.antiresonance_hz)]
    return (min(fa), max(fa)) if fa else None


def stroke_filters(params) -> list:
    """Resonance filters for the anti-resonance's walk over ``params`` (name, parameters):
    a notch at the geometric centre of the walk whose pole damping spans it (two depths),
    and a low-pass at half the lowest anti-resonance. Empty when the mode does not walk
    (ratio below :data:`WALK_LIMIT`) or the plant is rigid."""
    rng = antiresonance_range(params)
    if rng is None or rng[1] / rng[0] <= WALK_LIMIT:
        return []
    lo, hi = rng
    wc = 2 * math.pi * math.sqrt(lo * hi)
    spread = (hi - lo) / math.sqrt(lo * hi)
    out = []
    for zp in (max(0.7, 2 * spread), max(1.0, 4 * spread)):
        for depth in (0.07, 0.2):
            out.append(("notch", {"wn": wc, "zeta_zero": depth * zp, "zeta_pole": zp}))
    out.append(("lowpass", {"wn": 0.5 * 2 * math.pi * lo, "zeta": 0.5}))
    return out


class StrokePlants:
    """Plant responses P1, P2 (rad/A) at each design point on a frequency grid.

    Parameters
    ----------
    params : sequence of PlantParameters
    s : numpy.ndarray
        Complex frequencies (1/s).
    current_gains : tuple
        Current PI (kp, ki).
    """

    def __init__(self, params, s, current_gains):
        self.params = tuple(params)
        pairs = [plant_responses(s, p, *current_gains) for p in self.params]
        self.P1 = np.array([a for a, _ in pairs])
        self.P2 = np.array([b for _, b in pairs])
        self.N = np.array([p.N for p in self.params], float)[:, None]

    @property
    def count(self) -> int:
        return len(self.params)


def speed_references(p, params):
    """Plants the speed-loop crossover is set on: q0's, and the design point of the largest
    motor-side inertia J1 / N^2 when it exceeds q0's by more than the stroke check's
    :data:`~.stroke.INERTIA_SPREAD_LIMIT` (the speed loop's crossover falls in proportion
    to that inertia, so gains set on a light point lose their phase on the heavy one)."""
    heavy = max(params, key=lambda q: q.J1 / q.N**2)
    if heavy.J1 / heavy.N**2 > INERTIA_SPREAD_LIMIT * p.J1 / p.N**2:
        return (p, heavy)
    return (p,)


def result_slack(result) -> float:
    """Smallest normalized slack over a result's checks (as in the search's ranking)."""
    out = math.inf
    for c in result.requirements:
        if c.name == "bandwidth":
            sl = math.log(c.achieved / c.required) if c.achieved > 0 else -10.0
        else:
            sl = (c.achieved - c.required if c.sense == ">=" else c.required - c.achieved) / max(abs(c.required), 1.0)
        out = min(out, sl if math.isfinite(sl) else (10.0 if sl > 0 else -10.0))
    return out if result.margins.closed_loop_stable else out - 10.0


def missed_points(result) -> list:
    """Stroke points where the stroke check finds a missed margin row or instability: the
    point of each failing row's worst figure, and the least stable unstable point."""
    s = result.stroke
    if s is None:
        return []
    out = []
    if not s.all_stable:
        out.append(float(s.q[int(np.argmax(s.max_pole_real))]))
    worst = s.worst()
    key = {"gain_margin_over_stroke": "gain_margin_db", "phase_margin_over_stroke": "phase_margin_deg",
           "sensitivity_peak_over_stroke": "sensitivity_peak_db"}
    for c in result.requirements:
        if not c.passed and c.name in key and key[c.name] in worst:
            out.append(float(worst[key[c.name]]["q"]))
    return list(dict.fromkeys(out))
