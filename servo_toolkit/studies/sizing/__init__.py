"""Sizing along a duty cycle: the motor's torque-speed points against its envelope, RMS
torque and current, peak and regenerated power, winding temperature from a two-node thermal
network, screw and bearing life L10, and the ratio choice.

One module per step: :mod:`.cycle` (duty cycle -> motion), :mod:`.loads` (inverse
dynamics along it), :mod:`.envelope` (limits and margins), :mod:`.thermal`, :mod:`.life`,
:mod:`.sweep` (the ratio sweep) and :mod:`.sweep_plot` (its figure), :mod:`.closed_loop` (the loads from the nonlinear
closed-loop simulation), :mod:`.result` and :mod:`.run` (``size``).
"""

from .result import SizingResult
from .run import size

__all__ = ["SizingResult", "size"]
