"""Loop design, margins, requirement checks and robustness of a scene's position loop."""

from .closed_loop import linear_closed_loop, open_loop
from .design import design, evaluate
from .margins import Margins, loop_margins
from .requirements import Check, Requirement, parse_override, requirements_of, robust_requirements
from .result import DesignResult
from .robust_design import mode_range
from .robustness import RobustnessResult, robustness

__all__ = ["Check", "DesignResult", "Margins", "Requirement", "RobustnessResult", "design", "evaluate",
           "linear_closed_loop", "loop_margins", "mode_range", "open_loop", "parse_override",
           "requirements_of", "robust_requirements", "robustness"]
