"""Excitations for a rig's drive: a low-crest-factor multisine, a PRBS or a periodic chirp
over a band from the scene's loop, as large as its current, voltage and stroke limits allow
(and, where it can be, above its breakaway and backlash levels), with the model's run of it
as the log to expect.

One module per step: :mod:`.signals` (one period of each signal), :mod:`.plan` (band,
period, lines, length), :mod:`.drive` (the drive taking it, as the model's controller, and
its linear loop), :mod:`.levels` (limits and levels), :mod:`.run` (``excite``) and
:mod:`.result`.
"""

from .result import ExcitationResult
from .run import excite
from .signals import SIGNALS

__all__ = ["ExcitationResult", "SIGNALS", "excite"]
