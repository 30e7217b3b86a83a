"""One unit per quantity wherever a result is shown: the report, the CLI, JSON and Jupyter.

Stiffness at the output is in N*m/rad (N/m for an output travel), inertia in kg*m^2 (a mass
in kg for a travel), as :class:`servo_toolkit.core.output_units.OutputUnit` gives them and
``servo-toolkit design`` prints them; angles are shown in deg, frequencies in Hz. Axis
labels read ``quantity [unit]``; a dimensionless value carries no unit at all.
"""

from __future__ import annotations

from ..core.output_units import OutputUnit

#: the unit cell of a dimensionless value (a ratio, an efficiency, a damping ratio)
DIMENSIONLESS = ""


def stiffness_unit(linear: bool = False) -> str:
    """Unit of a stiffness at the output (SI, no scaling): ``"N*m/rad"`` or ``"N/m"``."""
    return OutputUnit("m" if linear else "rad").stiffness


def inertia_unit(linear: bool = False) -> str:
    """Unit of an inertia at the output (SI): ``"kg*m^2"``, or ``"kg"`` for a travel."""
    return OutputUnit("m" if linear else "rad").inertia


def label(quantity: str, unit: str = DIMENSIONLESS) -> str:
    """An axis or column label, ``"quantity [unit]"``; the bare quantity when dimensionless."""
    return f"{quantity} [{unit}]" if unit else quantity
