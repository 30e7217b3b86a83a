"""The ``frequency_sweep`` study kind: its scene keys, runner, result, command and report
section."""

from __future__ import annotations

from ...scene.study_kind import StudyKind
from ...scene.study_schema import RUN_KEYS, SINE_KEYS

SWEEP = StudyKind(
    name="frequency_sweep",
    summary="nonlinear closed-loop frequency response by sine dwell, against the linear loop",
    schema={**SINE_KEYS, "frequencies": ("sweep", None), **RUN_KEYS},
    run="servo_toolkit.studies.sweep.compute:sweep",
    result="servo_toolkit.studies.sweep.result:SweepResult",
    command="sweep",
    section="servo_toolkit.report.sections_studies:sweep",
    section_title="Nonlinear frequency sweep against the linear loop",
    section_key="sweep",
    section_rank=10,
    stroke="operating_point",
    runs_other_kinds=True,
)

KINDS = (SWEEP,)

__all__ = ["KINDS", "SWEEP"]
