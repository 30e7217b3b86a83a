"""The tolerance study (``servo-toolkit tolerances``): what fraction of built actuators meets
the requirements, and which tolerance to tighten. The scene's ``[tolerances]`` schema is
:mod:`servo_toolkit.scene.tolerances`.

:mod:`.run` (``tolerance_study``: draws, margins, yields, sensitivity), :mod:`.time_runs`
(the variants' batched nonlinear time runs), :mod:`.figures` (the figures judged and their
requirements), :mod:`.corner` (the worst corner of the tolerance box) and :mod:`.result`
(``ToleranceResult``, ``WorstCorner``).
"""

from .corner import MAX_CORNERS, worst_corner
from .figures import FIGURES
from .result import ToleranceResult, WorstCorner, shown_unit
from .run import sampling_notes, tolerance_study
from .time_runs import ToleranceRuns, tolerance_runs

__all__ = ["FIGURES", "MAX_CORNERS", "ToleranceResult", "ToleranceRuns", "WorstCorner", "sampling_notes",
           "shown_unit", "tolerance_runs", "tolerance_study", "worst_corner"]
