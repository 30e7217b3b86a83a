"""Permanent-magnet DC motor."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..core.fields import Fields, require


#: largest value of each motor constant the models are conditioned for (SI): far beyond any
#: electric motor (a 1 MW machine has Kt of a few hundred N*m/A)
PLAUSIBLE_MAX = {"resistance": 1e15, "inductance": 10.0, "torque_constant": 1e4, "back_emf_constant": 1e4,
                 "rotor_inertia": 1e4, "viscous_friction": 1e6, "coulomb_friction": 1e6}


@dataclass(frozen=True)
class DCMotor:
    """Armature-controlled DC motor, SI units.

    Parameters
    ----------
    resistance : float
        Armature resistance R (ohm).
    inductance : float
        Armature inductance L (H); 0 means neglected.
    torque_constant : float
        Kt (N*m/A).
    back_emf_constant : float
        Ke (V*s/rad).
    rotor_inertia : float
        Jm (kg*m^2).
    viscous_friction, coulomb_friction : float
        b (N*m*s/rad) and Tc (N*m).
    voltage_limit, current_limit : float
        Supply voltage (V) and current limit (A); ``inf`` when absent.
    """

    resistance: float
    inductance: float
    torque_constant: float
    back_emf_constant: float
    rotor_inertia: float
    viscous_friction: float = 0.0
    coulomb_friction: float = 0.0
    voltage_limit: float = math.inf
    current_limit: float = math.inf

    @property
    def electrical_time_constant(self) -> float:
        """L/R (s)."""
        return self.inductance / self.resistance

    @property
    def stall_torque(self) -> float:
        """Torque at the current limit, or at the voltage limit on a stalled rotor (N*m)."""
        return self.torque_constant * min(self.current_limit, self.voltage_limit / self.resistance)

    @classmethod
    def from_table(cls, f: Fields) -> "DCMotor":
        """Build from a ``[motor]`` table."""
        kind = f.text("kind", "dc")
        require(kind == "dc", f.key("kind"), f"only kind = 'dc' is supported (got {kind!r})")
        motor = cls(
            resistance=f.quantity("resistance", "ohm", rule="positive"),
            inductance=f.quantity("inductance", "H", 0.0, rule="nonnegative"),
            torque_constant=f.quantity("torque_constant", "N*m/A", rule="positive"),
            back_emf_constant=f.quantity("back_emf_constant", "V*s/rad", rule="positive"),
            rotor_inertia=f.quantity("rotor_inertia", "kg*m^2", rule="positive"),
            viscous_friction=f.quantity("viscous_friction", "N*m*s/rad", 0.0, rule="nonnegative"),
            coulomb_friction=f.quantity("coulomb_friction", "N*m", 0.0, rule="nonnegative"),
            voltage_limit=f.quantity("voltage_limit", "V", math.inf),
            current_limit=f.quantity("current_limit", "A", math.inf),
        )
        for key, top in PLAUSIBLE_MAX.items():  # beyond these the plant's matrices lose their digits
            value = getattr(motor, key)
            require(value <= top, f.key(key), f"must be at most {top:g} (got {value:g}): outside the range "
                    "of electric motors the models are conditioned for")
        require(motor.resistance >= 1e-6, f.key("resistance"), f"must be at least 1e-06 ohm (got {motor.resistance:g})")
        require(motor.voltage_limit > 0, f.key("voltage_limit"), "must be positive")
        require(motor.current_limit > 0, f.key("current_limit"), "must be positive")
        f.check_unknown()
        return motor
