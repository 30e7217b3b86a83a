"""Linear plant blocks: python-control systems with named signals at an operating point.

Modules: :mod:`.linear` (the motor, drivetrain and load of an actuator, the rigid and
two-mass reductions of the drivetrain's chain), :mod:`.current_loop` (the analog current PI
and the sampling delay on the current command), :mod:`.chain_plant` (every node and
mode of the chain), :mod:`.sampled` (motor speed per current as a drive's log samples them at
its control instants), :mod:`.signals` (shared signal names) and
:mod:`.platform` (the crossed-arch deflection platform of seed 003 as a MIMO plant).
"""

from .chain_plant import chain_plant
from .current_loop import current_controller, current_loop_gains, sample_delay
from .linear import (DEFAULT_STRUCTURAL_DAMPING, PLANT_OUTPUTS, PlantParameters, mechanics, plant, plant_matrices,
                     plant_parameters, rigid_plant, spring_damping, two_mass_damping, two_mass_plant)

__all__ = ["DEFAULT_STRUCTURAL_DAMPING", "PLANT_OUTPUTS", "PlantParameters", "chain_plant", "current_controller",
           "current_loop_gains", "mechanics", "plant", "plant_matrices", "plant_parameters", "rigid_plant",
           "sample_delay", "spring_damping", "two_mass_damping", "two_mass_plant"]
