"""The stiffness chain study (seed 001): each stage's stiffness reflected to the output and
its share of the series compliance.

:mod:`.compute` runs it (:func:`~.compute.stiffness_study`, the output points it is taken
at); :mod:`.result` holds :class:`~.result.StiffnessResult` (table, card, figure). The names
below are imported on first use.
"""

from __future__ import annotations

__all__ = ["DEFAULT_ANGLES_DEG", "StiffnessResult", "default_angles_deg", "output_points", "stiffness_study"]


def __getattr__(name: str):
    if name in ("stiffness_study", "output_points", "default_angles_deg", "DEFAULT_ANGLES_DEG"):
        from . import compute as module
    elif name == "StiffnessResult":
        from . import result as module
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(module, name)
