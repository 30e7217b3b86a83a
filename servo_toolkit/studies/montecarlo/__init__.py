"""The nonlinear Monte Carlo (``servo-toolkit montecarlo``): many variants of the scene
(load inertia, drivetrain stiffness) run in time in one compiled batch, each checked at its
own parameters.

:mod:`.run` (``montecarlo``: the variants, their batch and its chunks), :mod:`.variant_step`
(each variant's own check of the batch's RK4 step), :mod:`.result` (``MonteCarloResult``) and
:mod:`.check` (its rows of the requirement table that ``check`` and the report read).
"""

from .check import check_cases, montecarlo_checks, montecarlo_requirements, result_checks, spec_montecarlo
from .result import MonteCarloResult
from .run import CHUNK_SIZE, montecarlo
from .variant_step import step_check

__all__ = ["CHUNK_SIZE", "MonteCarloResult", "check_cases", "montecarlo", "montecarlo_checks",
           "montecarlo_requirements", "result_checks", "spec_montecarlo", "step_check"]
