"""Linear plant blocks: python-control systems with named signals at an operating point.

Modules: :mod:`.linear` (the motor, current loop, drivetrain and load of an actuator) and
:mod:`.platform` (the crossed-arch deflection platform of seed 003 as a MIMO plant).
"""

from .linear import (DEFAULT_STRUCTURAL_DAMPING, PLANT_OUTPUTS, PlantParameters, current_controller,
                     current_loop_gains, mechanics, plant, plant_matrices, plant_parameters, rigid_plant,
                     sample_delay, spring_damping, two_mass_plant)

__all__ = ["DEFAULT_STRUCTURAL_DAMPING", "PLANT_OUTPUTS", "PlantParameters", "current_controller",
           "current_loop_gains", "mechanics", "plant", "plant_matrices", "plant_parameters", "rigid_plant",
           "sample_delay", "spring_damping", "two_mass_plant"]
