"""Leave out what a study does not need: the reduced model, why, and its measured error
(``servo-toolkit reduce``).

One module per step: :mod:`.estimates` (``plan_reduction``: each effect's a-priori estimate
at a study's frequencies and amplitudes), :mod:`.friction` (friction that holds, node by
node), :mod:`.choice` (what to leave out within the tolerance: the plan and its options),
:mod:`.run` (``reduce``: the study on the full and the reduced model, their measured
difference and each effect's own cost) and :mod:`.result` (``ReductionResult``).
"""

from .choice import Effect, ReductionPlan
from .estimates import DEFAULT_TOLERANCE, plan_reduction
from .result import EffectCost, ReductionResult
from .run import reduce, reduced_options, time_points

__all__ = ["DEFAULT_TOLERANCE", "Effect", "EffectCost", "ReductionPlan", "ReductionResult", "plan_reduction",
           "reduce", "reduced_options", "time_points"]
