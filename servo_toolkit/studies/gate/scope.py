"""What ``servo-toolkit design`` judges and what it leaves to ``servo-toolkit check``.

``design`` judges the loop's rows: the linear margins at q0 and over the stroke, the
large-signal rows (unless ``--linear-only``) and, with ``[robustness]``, the robustness rows
over the variants. ``check`` judges these and the rest of the gate (:func:`.table.gate`):
the nonlinear step and requirement sine (:mod:`servo_toolkit.studies.actuator`), the sizing
of a ``[duty_cycle]``, the Monte Carlo time runs of ``[robustness]`` and the yield of
``[tolerances]``. :func:`left_to_check` says which of them a scene asks for, so a design
that exits 0 never reads as every requirement met.
"""

from __future__ import annotations


def left_to_check(scene, linear_only: bool = False) -> str:
    """One note: the rows of ``scene``'s gate that ``design`` does not judge, the scene's
    own time requirements named by their keys.

    Parameters
    ----------
    scene : Scene
    linear_only : bool
        ``design --linear-only``: the large-signal rows are left out too.
    """
    from ..actuator.spec import ROW_KEYS
    given = scene.requirements.time
    set_rows = [(row, key) for row, key in ROW_KEYS.items() if getattr(given, key, None) is not None]
    if set_rows:
        parts = [f"{', '.join(r for r, _ in set_rows)} (the scene's {', '.join(k for _, k in set_rows)}) and "
                 f"the other rows of the nonlinear step and sine at their defaults"]
    else:
        parts = [f"the rows of the nonlinear step and sine ({', '.join(ROW_KEYS)}) at their defaults"]
    parts[0] += " (full model, friction that holds)"
    if linear_only:
        parts.append("large_signal_gain, large_signal_phase (--linear-only)")
    if getattr(scene, "duty_cycle", None) is not None:
        parts.append("the sizing rows of the [duty_cycle] (envelope_*, thermal_margin, life_*, static_load_*)")
    spec = getattr(scene, "robustness", None)
    mc = [f"robust_{n}" for n in ("tracking_error", "peak_current")
          if spec is not None and getattr(spec, f"max_{n}", None) is not None]
    if mc:
        parts.append(f"{', '.join(mc)} (nonlinear time runs over the [robustness] variants)")
    tol = getattr(scene, "tolerances", None)
    if tol is not None and tol.min_yield is not None:
        parts.append("yield, yield_* (the [tolerances] study against min_yield)")
    return "not judged here: " + "; ".join(parts) + ": servo-toolkit check judges them (exit 1 when one fails)"


__all__ = ["left_to_check"]
