"""The ``simulate`` study: a time simulation of the closed loop along a study's sine (or at
a constant voltage, open loop).

:mod:`.kind` describes the study kind (its scene keys, runner, result, command and report
section); :mod:`.run` runs it (:func:`~.run.simulate_study`), :mod:`.reference` turns a
study into the run's command. The names below are imported on first use, so that reading
the kind's description imports no computation.
"""

from __future__ import annotations

__all__ = ["check_sine_frequency", "resolve_method", "resolve_run", "run_spec", "simulate_study"]


def __getattr__(name: str):
    if name in ("simulate_study", "resolve_run", "resolve_method"):
        from . import run as module
    elif name in ("run_spec", "check_sine_frequency"):
        from . import reference as module
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(module, name)
