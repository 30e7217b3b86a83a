"""Friction at a drivetrain stage's output: the bearings, guides or seals of the member that
moves with the stage's output coordinate (``[[drivetrain]]`` keys ``coulomb_friction``,
``static_friction``, ``stribeck_speed``, ``viscous_friction``)."""

from __future__ import annotations

from dataclasses import dataclass

from .base import check_breakaway, check_fields, require_friction_values

#: the scene keys of a stage's friction
KEYS = ("coulomb_friction", "static_friction", "stribeck_speed", "viscous_friction")


@dataclass(frozen=True)
class StageFriction:
    """Friction at a stage's output, in the stage's output units.

    Parameters
    ----------
    coulomb_friction : float
        Sliding (Coulomb) level Tc (N*m at a shaft; N at a travel).
    static_friction : float or None
        Breakaway level Ts >= Tc (None: Ts = Tc).
    stribeck_speed : float
        Output speed over which the friction falls from Ts to Tc (rad/s; m/s); 0: at once.
    viscous_friction : float
        Viscous coefficient (N*m*s/rad; N*s/m).
    """

    coulomb_friction: float = 0.0
    static_friction: float | None = None
    stribeck_speed: float = 0.0
    viscous_friction: float = 0.0

    #: each field's SI unit (at a shaft, at a travel) and rule
    #: (:func:`~servo_toolkit.components.base.check_fields`)
    FIELD_RULES = {"coulomb_friction": (("N*m", "N"), "nonnegative"), "static_friction": (("N*m", "N"), "nonnegative"),
                   "stribeck_speed": (("rad/s", "m/s"), "nonnegative"),
                   "viscous_friction": (("N*m*s/rad", "N*s/m"), "nonnegative")}

    def __post_init__(self):
        check_fields(self, self.FIELD_RULES, "StageFriction")
        check_breakaway(self, "StageFriction.static_friction")

    @property
    def breakaway(self) -> float:
        """Ts: the static friction, or the Coulomb friction where none is given."""
        return self.coulomb_friction if self.static_friction is None else self.static_friction

    @classmethod
    def from_fields(cls, f, travel: bool) -> "StageFriction | None":
        """The friction keys of a ``[[drivetrain]]`` table (None when it gives none);
        ``travel``: the stage's output is a travel (N, m/s, N*s/m), else a shaft angle."""
        units = ("N", "m/s", "N*s/m") if travel else ("N*m", "rad/s", "N*m*s/rad")
        values = dict(coulomb_friction=f.quantity("coulomb_friction", units[0], 0.0, rule="nonnegative"),
                      static_friction=(f.quantity("static_friction", units[0], rule="nonnegative")
                                       if f.has("static_friction") else None),
                      stribeck_speed=f.quantity("stribeck_speed", units[1], 0.0, rule="nonnegative"),
                      viscous_friction=f.quantity("viscous_friction", units[2], 0.0, rule="nonnegative"))
        require_friction_values(f, values, ("coulomb_friction", "stribeck_speed", "viscous_friction"), units[0])
        fr = cls(**values)
        return None if fr == cls() else fr


__all__ = ["KEYS", "StageFriction"]
