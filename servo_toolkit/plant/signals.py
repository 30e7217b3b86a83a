"""Names and defaults shared by the linear plant blocks (:mod:`.linear`, :mod:`.chain_plant`)."""

PLANT_OUTPUTS = ("theta", "omega_m", "i", "omega")
DEFAULT_STRUCTURAL_DAMPING = 0.02
"""Damping ratio of the drivetrain mode when the scene gives none (lightly damped steel)."""

__all__ = ["DEFAULT_STRUCTURAL_DAMPING", "PLANT_OUTPUTS"]
