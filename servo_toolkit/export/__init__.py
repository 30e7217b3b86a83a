"""Controller export: the designed cascade as ``controller.json`` and portable C99 sources.

:func:`export` turns a :func:`servo_toolkit.design` result into discrete blocks
(:mod:`.blocks`), optionally quantizes them to fixed point (:mod:`.quantize`), emits C
(:mod:`.c_code`) and writes the folder atomically (:mod:`.writer`).
"""

from .blocks import Biquad, Blocks, blocks_of, tustin_to_continuous
from .build import export, quantized_controller
from .quantize import Quantized, quantize
from .result import ExportResult

__all__ = ["Biquad", "Blocks", "ExportResult", "Quantized", "blocks_of", "export", "quantize",
           "quantized_controller", "tustin_to_continuous"]
