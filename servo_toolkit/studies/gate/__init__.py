"""The requirement table ``servo-toolkit check`` gates on and the report shows: one row per
requirement with a stable ID (its JUnit testcase name).

:mod:`.table` (``RequirementRow``, the rows of each source, ``gate`` and its ``Gate``),
:mod:`.large_signal` (the nonlinear closed loop on the requirement sine against the linear
loop: the ``large_signal_*`` rows) and :mod:`.measured` (the ``measured_*`` rows of a loop
closed on a measured plant response, ``check --plant-frf``); :mod:`.scope` names the rows
``design`` leaves to ``check``.
"""

from .large_signal import GAIN_TOLERANCE_DB, PHASE_TOLERANCE_DEG, LargeSignal, fit_sine, with_large_signal
from .measured import measured_rows
from .scope import left_to_check
from .table import (LABELS, SIZING_ROWS, STATUSES, YIELD_LABELS, Gate, RequirementRow, check_row, design_rows,
                    failed_count, gate, montecarlo_rows, robust_rows, sizing_rows, unavailable_rows, yield_rows)

__all__ = ["GAIN_TOLERANCE_DB", "LABELS", "PHASE_TOLERANCE_DEG", "SIZING_ROWS", "STATUSES", "YIELD_LABELS", "Gate",
           "LargeSignal", "RequirementRow", "check_row", "design_rows", "failed_count", "fit_sine", "gate",
           "left_to_check", "measured_rows", "montecarlo_rows", "robust_rows", "sizing_rows", "unavailable_rows",
           "with_large_signal", "yield_rows"]
