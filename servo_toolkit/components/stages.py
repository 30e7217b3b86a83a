"""The drivetrain stages a scene may name, by their ``KIND``: the one list a new stage joins
(each stage's facts, its units, ratio keys and display units, live on its class:
:class:`~servo_toolkit.components.base.Stage`)."""

from __future__ import annotations

from types import MappingProxyType

from .ball_screw import BallScrew
from .cam.geometry import Cam
from .compliance import Compliance
from .gear import GearTrain
from .linkage import RockerLinkage
from .roller_screw.stages import RollerScrew

#: every stage class, in the order the scene reference lists them
STAGES = (GearTrain, BallScrew, RockerLinkage, Compliance, Cam, RollerScrew)
#: scene ``kind`` -> stage class
STAGE_KINDS = MappingProxyType({cls.KIND: cls for cls in STAGES})
#: scene ``kind`` -> (input, output): ``rotary`` (a shaft angle) or ``travel`` (a linear
#: position); a compliance passes on what it receives. The motor delivers a rotary input.
STAGE_IO = MappingProxyType({cls.KIND: cls.IO for cls in STAGES})

__all__ = ["STAGES", "STAGE_IO", "STAGE_KINDS"]
