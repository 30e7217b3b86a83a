"""A bound on the tracking error as a scene gives it: an angle, or a length for an output
travel (``[robustness]`` and ``[tolerances]`` ``max_tracking_error``)."""

from __future__ import annotations

from ..errors import SceneError


def tracking_error(f) -> dict:
    """``max_tracking_error`` of a ``[robustness]`` table: an angle, a length (an output
    travel) or a bare SI number, positive."""
    if not f.has("max_tracking_error"):
        return {}
    if not isinstance(f.raw("max_tracking_error"), str):
        return {"max_tracking_error": f.quantity("max_tracking_error", "rad", rule="positive")}
    for unit, dimension in (("rad", "angle"), ("m", "length")):
        try:
            value = f.quantity("max_tracking_error", unit, rule="positive")
        except SceneError as exc:
            if "positive" in str(exc) or "finite" in str(exc):
                raise
            continue
        return {"max_tracking_error": value, "tracking_error_dimension": dimension}
    raise SceneError(f.key("max_tracking_error"), "expected an angle (e.g. '0.5 deg') or, for an output "
                     "travel, a length (e.g. '0.2 mm')")


__all__ = ["tracking_error"]
