"""Identification: fit scene parameters to measured responses of the rig.

:func:`fit` takes a scene, a measurement (a frequency response or time traces, see
:func:`read_data`) and scene key paths, and returns a :class:`FitResult`;
:func:`calibrated_text` writes the scene file with the fitted values; :func:`simulated_log`
gives a drive's closed-loop log of a scene at its control instants.

The names below are imported on first use, so that reading a measurement (``check
--plant-frf`` reads one through :mod:`.data`) loads none of the fit's search and residual
machinery (scipy's optimizer and signal processing).
"""

from __future__ import annotations

import sys as _sys
from types import ModuleType as _ModuleType

__all__ = ["FitResult", "FrequencyData", "LoopData", "TimeData", "calibrated_text", "fit", "read_data",
           "simulated_log"]


def __getattr__(name: str):
    if name == "fit":
        from .fit import fit as value
    elif name == "FitResult":
        from .result import FitResult as value
    elif name == "calibrated_text":
        from .write import calibrated_text as value
    elif name == "simulated_log":
        from .loop_model import simulated_log as value
    elif name in ("FrequencyData", "LoopData", "TimeData", "read_data"):
        from . import data

        value = getattr(data, name)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


class _Package(_ModuleType):
    """The package, whose name ``fit`` is the function: loading the submodule of the same
    name (which binds the submodule on its package) binds the function instead."""

    def __setattr__(self, name, value):
        if name == "fit" and isinstance(value, _ModuleType):
            value = value.fit
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package
