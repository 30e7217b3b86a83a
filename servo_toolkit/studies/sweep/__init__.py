"""The ``frequency_sweep`` study: the nonlinear closed loop's frequency response by sine
dwell, against the linear loop.

:mod:`.kind` describes the study kind (its scene keys, runner, result, command and report
section); :mod:`.compute` runs the sweep, :mod:`.points` reads its frequencies and
amplitudes, :mod:`.result` holds :class:`~.result.SweepResult`. The names below are
imported on first use, so that reading the kind's description imports no computation.
"""

from __future__ import annotations

__all__ = ["DEFAULT_AMPLITUDE", "DEFAULT_FREQUENCY_HZ", "SweepResult", "check_sweep_frequencies", "linear_response",
           "study_points", "sweep"]


def __getattr__(name: str):
    if name in ("sweep", "linear_response"):
        from . import compute as module
    elif name in ("study_points", "check_sweep_frequencies", "DEFAULT_AMPLITUDE", "DEFAULT_FREQUENCY_HZ"):
        from . import points as module
    elif name == "SweepResult":
        from . import result as module
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(module, name)
