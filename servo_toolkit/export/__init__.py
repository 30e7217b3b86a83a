"""Controller export: the designed cascade as ``controller.json`` and portable C99 sources.

:func:`export` turns a :func:`servo_toolkit.design` result into discrete blocks
(:mod:`.blocks`), optionally quantizes them to fixed point (:mod:`.quantize`), emits C
(:mod:`.c_code`) and writes the folder atomically (:mod:`.writer`).
"""

import sys
import types

from .blocks import Biquad, Blocks, blocks_of, tustin_to_continuous
from .build import export, quantized_controller
from .quantize import Quantized, quantize
from .result import ExportResult

__all__ = ["Biquad", "Blocks", "ExportResult", "Quantized", "blocks_of", "export", "quantize",
           "quantized_controller", "tustin_to_continuous"]


class _ExportModule(types.ModuleType):
    """``servo_toolkit.export`` is both this package and the :func:`export` function: the
    package is imported on first use (``import servo_toolkit`` stays light), and calling it
    calls the function, whichever of the two the name is bound to."""

    def __call__(self, *args, **kwargs):
        return export(*args, **kwargs)


sys.modules[__name__].__class__ = _ExportModule
