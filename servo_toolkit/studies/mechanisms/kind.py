"""The seed mechanisms' study kinds, ``inverse_dynamics`` (the crossed-arch platform's ramp)
and ``mechanism_sweep`` (the cam drive at constant speed): their scene keys, runner and
result (their studies run through ``servo-toolkit simulate --study NAME``). They run only as a seed-mechanism study of a matching scene (:mod:`.dispatch`)."""

from __future__ import annotations

from ...scene.study_kind import StudyKind
from ..time.kind import SIMULATE

INVERSE_DYNAMICS = StudyKind(
    name="inverse_dynamics",
    summary="motor torques of the crossed-arch platform along a constant-rate ramp",
    schema={"rate_alpha": ("rad/s", "finite"), "rate_beta": ("rad/s", "finite"),
            "duration": ("s", "positive"), "external_moments": ("moments", None)},
    run="servo_toolkit.studies.mechanisms.dispatch:run_mechanism",
    result="servo_toolkit.studies.mechanisms.platform:PlatformRampResult",
    command=SIMULATE.command,
    in_report=False,
    mechanism_only=True,
)

MECHANISM_SWEEP = StudyKind(
    name="mechanism_sweep",
    summary="the cam drive at constant speed: motor torque along the cam's turn, per gravity direction",
    schema={"speed": ("rad/s", "positive"), "sample_time": ("s", "positive"),
            "gravity_tilts": (["rad"], "finite"), "gravity_headings": (["rad"], "finite")},
    run="servo_toolkit.studies.mechanisms.dispatch:run_mechanism",
    result="servo_toolkit.studies.cam.constant_speed:CamSweepResult",
    command=SIMULATE.command,
    in_report=False,
    mechanism_only=True,
)

KINDS = (INVERSE_DYNAMICS, MECHANISM_SWEEP)

__all__ = ["INVERSE_DYNAMICS", "KINDS", "MECHANISM_SWEEP"]
