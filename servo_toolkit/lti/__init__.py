"""Linear state-space blocks with named signals, in numpy: the toolkit's own linear algebra
for the loop's analyses, each step the same arithmetic python-control uses without Slycot.

:mod:`.system` the block (matrices, names, poles, zeros, frequency response) and the
python-control system made from it on request; :mod:`.convert` transfer function to and
from a block, the Pade delay and Tustin sampling; :mod:`.connect` blocks joined by their
signal names (python-control's ``interconnect``); :mod:`.analysis` stability margins and
bandwidth of a loop; :mod:`.lazy` the field of a result that holds a block and reads as a
python-control system."""

from .system import StateSpace, as_system, ss

__all__ = ["StateSpace", "as_system", "ss"]
