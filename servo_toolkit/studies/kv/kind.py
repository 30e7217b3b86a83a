"""The ``kv`` study kind: its scene keys, runner, result, command and report section."""

from __future__ import annotations

from ...scene.study_kind import StudyKind
from ...scene.study_schema import INERTIA, POSITION, SINE_KEYS

KV = StudyKind(
    name="kv",
    summary="dynamic-load factor Kv: peak loads along a prescribed sine with and without the load inertia",
    schema={**SINE_KEYS, "trajectory": (("sine",), None), "amplitude_at": (("output", "motor"), None),
            "offset": (POSITION, "finite"), "load_inertias": ([INERTIA], "nonnegative")},
    run="servo_toolkit.studies.kv.study:kv_study",
    result="servo_toolkit.studies.kv.result:KvResult",
    command="kv",
    section="servo_toolkit.report.sections_studies:kv_tables",
    section_title="Dynamic-load factor Kv",
    section_rank=20,
    stroke="offset",
    time_run=True,
)

KINDS = (KV,)

__all__ = ["KINDS", "KV"]
