"""The plant linearized at points of the stroke, computed once and read by every part of a
design that needs it: the search's scan for its design points
(:func:`.stroke_design.design_points`) and the check along the stroke
(:func:`.stroke.stroke_check`) take the same points, and
:func:`~servo_toolkit.plant.linear.plant_parameters` at a point costs milliseconds (the
chain's modes and damping there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, plant_parameters


@dataclass(frozen=True)
class PlantScan:
    """The plant linearized at the stroke check's points, made once for a design's scan of
    the stroke (:func:`.stroke_design.design_points`) and its check
    (:func:`.stroke.stroke_check`).

    Attributes
    ----------
    q : numpy.ndarray
        The points (rad), :func:`.stroke.stroke_points` with q0 among them.
    params : tuple of PlantParameters
        The plant at each point.
    model : str
    structural_damping : float
        What the plants were made with.
    """

    q: np.ndarray
    params: tuple
    model: str
    structural_damping: float


def plants_at(scene, q, model: str = "auto", structural_damping: float = DEFAULT_STRUCTURAL_DAMPING,
              scan: PlantScan | None = None) -> tuple:
    """:func:`~servo_toolkit.plant.linear.plant_parameters` at each point of ``q``: ``scan``'s
    when it was made at these points with this model and damping, else computed."""
    q = np.asarray(q, float)
    if (scan is not None and scan.model == model and scan.structural_damping == structural_damping
            and np.array_equal(scan.q, q)):
        return scan.params
    return tuple(plant_parameters(scene, x, model, structural_damping) for x in q)


__all__ = ["PlantScan", "plants_at"]
