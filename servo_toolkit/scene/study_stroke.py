"""A study's sine must fit the stroke: checked when the scene loads, and for a command's
``--amplitude``, before any run (a motion past the end stop is the user's figure, named as
such, not a run that fails later).

Each kind says about which centre its sine runs (:attr:`~.study_kind.StudyKind.stroke`): a
closed-loop sine (``frequency_sweep``, ``simulate``) about the design's operating point
(:func:`~servo_toolkit.drivetrain.operating_point.operating_point`); a Kv sine given at the
output about its ``offset`` (default mid-stroke). A cam chain's coordinate turns without
end and has no stroke to leave.
"""

from __future__ import annotations

from ..core.output_units import output_unit
from ..drivetrain.operating_point import operating_point
from ..errors import SceneError
from .study_kind import study_kinds

#: rounding allowance at the stroke ends (rad or m)
STROKE_TOL = 1e-12


def check_amplitude(scene, amplitude: float, key: str, center: float | None = None) -> None:
    """SceneError naming ``key`` unless ``center +- amplitude`` lies in the stroke.

    Parameters
    ----------
    scene : Scene
        A scene with a motor-driven drivetrain.
    amplitude : float
        Sine amplitude at the output (rad or m).
    key : str
        Scene key or command-line option the amplitude came from.
    center : float, optional
        Centre of the sine (default: the design's operating point).
    """
    drive = scene.drivetrain
    if drive.ends_in_cam:
        return
    lo, hi = drive.stroke
    q0 = operating_point(scene)[0] if center is None else float(center)
    if q0 - amplitude >= lo - STROKE_TOL and q0 + amplitude <= hi + STROKE_TOL:
        return
    u = output_unit(scene)
    room = max(0.0, min(q0 - lo, hi - q0))
    raise SceneError(key, f"the sine {u.text(q0 - amplitude)}..{u.text(q0 + amplitude)} about "
                          f"{u.text(q0)} leaves the stroke {u.text(lo)}..{u.text(hi)}: at most "
                          f"{u.text(room)} (got {u.text(amplitude)})")


def check_study_amplitudes(scene) -> None:
    """Every sine amplitude of the scene's studies within the stroke (:func:`check_amplitude`,
    naming ``studies.NAME.amplitude`` or ``studies.NAME.amplitudes``). A Kv amplitude given
    at the motor is checked when the study runs (it needs the ratio at its offset)."""
    if not scene.stages or scene.motor is None or scene.drivetrain.ends_in_cam:
        return
    center_default = None
    kinds = study_kinds()
    for study in scene.studies.values():
        stroke = kinds[study.kind].stroke
        if stroke == "operating_point":
            if center_default is None:
                center_default = operating_point(scene)[0]
            center = center_default
        elif stroke == "offset" and study.get("amplitude_at", "output") == "output":
            center = study.get("offset", scene.drivetrain.mid_stroke)
        else:
            continue
        for key in ("amplitude", "amplitudes"):
            values = study.get(key)
            for a in values if isinstance(values, list) else [] if values is None else [values]:
                check_amplitude(scene, a, study.key(key), center)


__all__ = ["check_amplitude", "check_study_amplitudes"]
