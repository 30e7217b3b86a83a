"""The ``simulate`` study kind: its scene keys, runner, result and command (the report
shows the loop's step and sine runs in its time section, not a section per study)."""

from __future__ import annotations

from ...scene.study_kind import StudyKind
from ...scene.study_schema import RUN_KEYS, SINE_KEYS

SIMULATE = StudyKind(
    name="simulate",
    summary="time simulation of the closed loop along a sine, or open loop at a constant voltage",
    schema={**SINE_KEYS, **RUN_KEYS, "voltage": ("V", "finite"), "frequencies": ("sweep", None),
            "speed_estimator": (("true", "difference", "kalman", "ideal"), None),
            "encoder_counts": ("count", None), "kalman_jerk": ("rad/s^3", "positive")},
    run="servo_toolkit.studies.time.run:simulate_study",
    result="servo_toolkit.sim.result:SimulationResult",
    command="simulate",
    in_report=False,
    stroke="operating_point",
    time_run=True,
    runs_other_kinds=True,
)

KINDS = (SIMULATE,)

__all__ = ["KINDS", "SIMULATE"]
