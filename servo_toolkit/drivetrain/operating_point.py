"""The design's operating point along the drivetrain's stroke.

A loop designed at one operating point q0 runs unchanged along the whole stroke; for a
cascade the speed-loop crossover scales as 1 / (motor-side inertia), so where the
motor-side reflected inertia J(q) / N(q)^2 varies much (a cam's dwell and rise) the loop is
designed where it is largest. The design (:mod:`servo_toolkit.loop`) and the simulation
model (:mod:`servo_toolkit.sim.model`) both take their default q0 from
:func:`operating_point`, so a simulation starts where the loop was designed.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SceneError
from ..core.units import argument_value

INERTIA_SPREAD_LIMIT = 1.5
"""Largest max/min ratio of the motor-side reflected inertia along the stroke for which the
loop is designed at mid-stroke; above it, at the largest inertia."""
SCAN_POINTS = 721
"""Operating points scanned for the inertia extremes (0.5 deg over a cam's turn)."""



def show_q(q: float, unit: str = "rad", digits: int = 4) -> str:
    """An operating point for text: degrees for an angle (``unit`` ``"rad"``), mm for a
    travel (``"m"``)."""
    return f"{q * 1e3:.{digits}g} mm" if unit == "m" else f"{math.degrees(q):.{digits}g} deg"


def _scan(drivetrain, points: int = SCAN_POINTS):
    q = np.linspace(*drivetrain.stroke, points)
    return q, drivetrain.motor_inertia(q)


def _plateau_middle(q, j) -> float:
    """The middle of the first run of grid points at the largest value of ``j`` (a cam's
    constant-velocity segment is a plateau of inertia, not a point)."""
    top = np.flatnonzero(j >= j.max() * (1 - 1e-9))
    run = top[: 1 + int(np.argmax(np.diff(top) > 1))] if np.any(np.diff(top) > 1) else top
    return float(q[run[len(run) // 2]])


def checked_q0(scene, q0, key: str = "q0") -> float:
    """An operating point given by its caller (rad, or m for a travel), as a float: finite
    and within the drivetrain's stroke (any angle of a chain ending in a cam, whose law is
    periodic), else one SceneError naming ``key`` (a bare number is rad: ``q0 = 10`` is 573
    deg, most likely a slip for 10 deg)."""
    drive = scene.drivetrain
    unit = drive.output_unit
    value = argument_value(q0, unit, key)  # a finite float (a Quantity converted), else one SceneError
    lo, hi = drive.stroke
    if drive.ends_in_cam or lo - 1e-9 * (hi - lo) <= value <= hi + 1e-9 * (hi - lo):
        return value
    si = "m" if unit == "m" else "rad"
    raise SceneError(key, f"must lie within the drivetrain stroke [{show_q(lo, unit, 6)}, {show_q(hi, unit, 6)}] "
                          f"(got {value:g} {si} = {show_q(value, unit, 6)}; a bare number is in {si})")


def operating_point(scene, q0=None) -> tuple[float, str | None]:
    """The design's operating point and, when it is not mid-stroke by default, why.

    Rule: an explicit ``q0`` wins. Otherwise, when the motor-side reflected inertia
    J(q) / N(q)^2 varies along the stroke by more than :data:`INERTIA_SPREAD_LIMIT` (max /
    min over :data:`SCAN_POINTS` points), the loop is designed where it is largest (the
    middle of the first plateau of that largest value); else at mid-stroke.

    Parameters
    ----------
    scene : Scene
    q0 : float or pint.Quantity, optional
        Operating point (rad, or m for an output travel; a Quantity is converted), within the
        stroke (:func:`checked_q0`).

    Returns
    -------
    q0 : float
        Operating point (rad).
    note : str or None
        The reason, for the result's notes (None for an explicit q0 or mid-stroke).
    """
    drive = scene.drivetrain
    if q0 is not None:
        return checked_q0(scene, q0), None
    q, j = _scan(drive)
    spread = float(j.max() / j.min())
    if spread <= INERTIA_SPREAD_LIMIT:
        return float(drive.mid_stroke), None
    at = _plateau_middle(q, j)
    u = drive.output_unit
    return at, (f"operating point q0 = {show_q(at, u)}, where the motor-side reflected inertia is "
                f"largest ({j.max():.4g} kg*m^2, {spread:.3g}x its smallest, {j.min():.4g} kg*m^2 at "
                f"{show_q(q[int(np.argmin(j))], u)}; rule: largest inertia when it varies by more "
                f"than {INERTIA_SPREAD_LIMIT:g}x, else mid-stroke); the loop is designed and checked over the stroke")


__all__ = ["INERTIA_SPREAD_LIMIT", "SCAN_POINTS", "checked_q0", "operating_point", "show_q"]
