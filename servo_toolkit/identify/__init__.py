"""Identification: fit scene parameters to measured responses of the rig.

:func:`fit` takes a scene, a measurement (a frequency response or time traces, see
:func:`read_data`) and scene key paths, and returns a :class:`FitResult`;
:func:`calibrated_text` writes the scene file with the fitted values.
"""

from .data import FrequencyData, LoopData, TimeData, read_data
from .fit import fit
from .result import FitResult
from .write import calibrated_text

__all__ = ["FitResult", "FrequencyData", "LoopData", "TimeData", "calibrated_text", "fit", "read_data"]
