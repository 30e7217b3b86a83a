"""The actuator judged in time: the designed loop's step and requirement sine through the
full nonlinear model with friction that holds, and the rows ``check`` gates on
(:mod:`.spec` the commands and bounds, :mod:`.runs` the runs, :mod:`.figures` the signal
figures, :mod:`.result` the rows)."""

from .result import ActuatorCheck, actuator_check

__all__ = ["ActuatorCheck", "actuator_check"]
