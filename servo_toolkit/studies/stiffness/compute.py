"""The stiffness chain study (seed 001): each stage's stiffness reflected to the output at
the given points, and its share (:func:`stiffness_study`).

The output coordinate q is an angle for a rotary output (the cam angle for a cam chain) and
a travel for a linear one (a chain ending in a screw, :attr:`Drivetrain.output_is_linear`).
Angles are given in deg, travels in mm; both must be finite and inside the drivetrain's
stroke (a cam chain is periodic: any finite cam angle).
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import SceneError
from ...core.angles import RAD_PER_DEG
from ...core.units import argument_values
from .result import StiffnessResult

DEFAULT_ANGLES_DEG = (-30.0, 0.0, 10.0, 30.0)


def default_angles_deg(drivetrain) -> tuple:
    """The default output angles (deg): :data:`DEFAULT_ANGLES_DEG` when they lie in the
    stroke (the reference EMA's), else the stroke's ends and middle (a cam: its turn's
    quarters)."""
    lo, hi = (math.degrees(x) for x in drivetrain.stroke)
    if drivetrain.ends_in_cam:
        return (0.0, 90.0, 180.0, 270.0)
    if lo - 1e-9 <= min(DEFAULT_ANGLES_DEG) and max(DEFAULT_ANGLES_DEG) <= hi + 1e-9:
        return DEFAULT_ANGLES_DEG
    return (lo, 0.5 * (lo + hi), hi)


def output_points(drive, angles_deg=None, positions_mm=None) -> tuple[np.ndarray, np.ndarray]:
    """Validated output coordinates: q (rad, or m for a linear output) and the values given.

    Parameters
    ----------
    drive : Drivetrain
    angles_deg : sequence of float or pint.Quantity, optional
        Output angles (deg, a Quantity converted) of a rotary output; default -30, 0, 10, 30.
    positions_mm : sequence of float or pint.Quantity, optional
        Output travels (mm, a Quantity converted) of a linear output; default mid-stroke.

    Returns
    -------
    q, values : numpy.ndarray
        SI coordinates and the same points in deg or mm.

    Raises
    ------
    SceneError
        Key ``angle`` or ``position``: the wrong kind of coordinate for this output, a
        non-finite value, or a value outside :attr:`Drivetrain.stroke`.
    """
    lo, hi = drive.stroke
    if drive.output_is_linear:
        if angles_deg is not None:
            raise SceneError("angle", "the output of this drivetrain is a travel (m), not an angle: "
                             "give positions in mm (--position MM)")
        key, unit, scale = "position", "mm", 1e-3
        values = [drive.mid_stroke / scale] if positions_mm is None else positions_mm
    else:
        if positions_mm is not None:
            raise SceneError("position", "the output of this drivetrain is an angle: give angles "
                             "in deg (--angle DEG)")
        key, unit, scale = "angle", "deg", RAD_PER_DEG
        values = (default_angles_deg(drive) if angles_deg is None else angles_deg)
    values = argument_values(values, unit, key)
    if values.size == 0:
        raise SceneError(key, "give at least one value")
    q = values * scale
    if not drive.ends_in_cam:  # a cam law is periodic: any finite cam angle is fine
        tol = 1e-9 * max(1.0, hi - lo)
        out = values[(q < lo - tol) | (q > hi + tol)]
        if out.size:
            raise SceneError(key, f"must lie within the drivetrain stroke [{lo / scale:.6g}, "
                             f"{hi / scale:.6g}] {unit} (got {out[0]:g} {unit})")
    return q, values


def stiffness_study(scene, angles_deg=None, positions_mm=None, *, min_ratio: float = 10.0,
                    within: float = 10.0) -> StiffnessResult:
    """Reflect each stage's stiffness to the output at the given points.

    Parameters
    ----------
    scene : Scene
    angles_deg : sequence of float or pint.Quantity, optional
        Output angles (deg: a bare number is in deg here, a Quantity is converted) of a rotary
        output (q for a cam chain); default -30, 0, 10, 30.
    positions_mm : sequence of float or pint.Quantity, optional
        Output travels (mm, a Quantity converted) of a linear output; default mid-stroke.
    min_ratio, within : float
        Thresholds of seed 001's neglect criterion (see :class:`NeglectCriterion`).

    Returns
    -------
    StiffnessResult

    Raises
    ------
    SceneError
        See :func:`output_points`.
    """
    drive = scene.drivetrain
    q, values = output_points(drive, angles_deg, positions_mm)
    chain = drive.stiffness(q)
    n, _ = drive.ratio(q)
    j, _ = drive.inertia(q)
    linear = drive.output_is_linear
    crit = chain.criterion(min_ratio, within) if chain.names else None
    return StiffnessResult(
        angles_deg=np.full(q.size, np.nan) if linear else values, names=chain.names,
        stage_stiffness=chain.stage_stiffness, shares=chain.shares, total=chain.total, ratio=n,
        reflected_inertia=j, negligible=chain.negligible(), output_unit=drive.output_unit,
        positions_mm=values if linear else None, criterion=crit, native_stiffness=chain.native_stiffness,
        native_units=chain.native_units, native_ratio=chain.ratio_to_output, display=scene.display)
