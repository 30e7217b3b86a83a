"""A series compliance (housing, mounting, shaft) and the load."""

from __future__ import annotations

from dataclasses import dataclass

from ..core.fields import Fields
from .base import DAMPING_RATIO_RANGE, Jet, Spring, Stage, check_breakaway, check_fields, require_friction_values


@dataclass(frozen=True)
class Compliance(Stage):
    """A rigid-ratio (1:1) stage that only adds a spring at its place in the chain.

    Parameters
    ----------
    name : str
    stiffness : float
        N*m/rad for rotary coordinates, N/m for linear ones.
    at : str
        ``"output"`` (the coordinate after the previous stage, the usual case).
    damping_ratio : float or None
        Damping ratio of the compliance (:mod:`servo_toolkit.drivetrain.chain_damping`);
        None: the model's default structural damping.
    """

    KIND = "compliance"
    IO = (None, None)
    UNITS = (None, None, None)
    RATIO_KEYS = None
    DISPLAY_UNITS = ()

    name: str
    stiffness: float
    at: str = "output"
    damping_ratio: float | None = None

    #: each field's SI unit (at a shaft, at a travel) and rule
    #: (:func:`~servo_toolkit.components.base.check_fields`)
    FIELD_RULES = {"stiffness": (("N*m/rad", "N/m"), "positive"), "damping_ratio": ("dimensionless", "nonnegative")}

    def __post_init__(self):
        check_fields(self, self.FIELD_RULES, "Compliance")

    def map(self, z) -> Jet:
        return Jet.linear(z, 1.0)

    def springs(self, z) -> list[Spring]:
        return [Spring(self.name, self.stiffness, Jet.linear(z, 1.0), self.damping_ratio)]

    @classmethod
    def from_table(cls, f: Fields) -> "Compliance":
        """Build from a ``[[drivetrain]]`` table of kind ``compliance``."""
        stage = cls(name=f.text("name", "compliance"),
                    stiffness=f.quantity("stiffness", "N*m/rad", rule="positive"),
                    at=f.text("at", "output", choices={"output"}),
                    damping_ratio=f.number("damping_ratio", None, rule="nonnegative", bounds=DAMPING_RATIO_RANGE))
        f.check_unknown()
        return stage


@dataclass(frozen=True)
class Load:
    """What the output drives, at the output coordinate.

    Parameters
    ----------
    inertia : float
        kg*m^2 (for an output travel, a chain ending in a screw: the load's mass, kg).
    hinge_moment : float
        Constant moment opposing positive motion (N*m; a force, N, for an output travel).
    hinge_stiffness : float
        Spring moment per output angle (N*m/rad; N/m for an output travel).
    damping : float
        N*m*s/rad (N*s/m for an output travel).
    coulomb_friction : float
        Friction moment Tc of the load's bearings or guides while it slides (N*m; N for an
        output travel).
    static_friction : float or None
        Breakaway moment Ts >= Tc (None: Ts = Tc).
    stribeck_speed : float
        Output speed over which the friction falls from Ts to Tc (rad/s; m/s); 0: at once.
    """

    inertia: float = 0.0
    hinge_moment: float = 0.0
    hinge_stiffness: float = 0.0
    damping: float = 0.0
    coulomb_friction: float = 0.0
    static_friction: float | None = None
    stribeck_speed: float = 0.0

    #: each field's SI unit (an output angle, an output travel) and rule
    #: (:func:`~servo_toolkit.components.base.check_fields`)
    FIELD_RULES = {"inertia": (("kg*m^2", "kg"), "nonnegative"), "hinge_moment": (("N*m", "N"), "finite"),
                   "hinge_stiffness": (("N*m/rad", "N/m"), "finite"),
                   "damping": (("N*m*s/rad", "N*s/m"), "nonnegative"),
                   "coulomb_friction": (("N*m", "N"), "nonnegative"), "static_friction": (("N*m", "N"), "nonnegative"),
                   "stribeck_speed": (("rad/s", "m/s"), "nonnegative")}

    def __post_init__(self):
        check_fields(self, self.FIELD_RULES, "load")
        check_breakaway(self, "load.static_friction")

    @property
    def breakaway(self) -> float:
        """Ts: the static friction, or the Coulomb friction where none is given."""
        return self.coulomb_friction if self.static_friction is None else self.static_friction

    @classmethod
    def from_table(cls, f: Fields, linear: bool = False) -> "Load":
        """Build from a ``[load]`` table; ``linear``: the output is a travel, so the values are a
        mass, a force, N/m and N*s/m."""
        units = (("kg", "N", "N/m", "N*s/m", "m/s") if linear else
                 ("kg*m^2", "N*m", "N*m/rad", "N*m*s/rad", "rad/s"))
        typical = (1e-3, 1e5, "g") if linear else (1e-7, 1e4, "g*cm^2")  # a carriage's mass, a load's inertia
        values = dict(inertia=f.quantity("inertia", units[0], 0.0, rule="nonnegative", typical=typical),
                      hinge_moment=f.quantity("hinge_moment", units[1], 0.0, rule="finite"),
                      hinge_stiffness=f.quantity("hinge_stiffness", units[2], 0.0, rule="finite"),
                      damping=f.quantity("damping", units[3], 0.0, rule="nonnegative"),
                      coulomb_friction=f.quantity("coulomb_friction", units[1], 0.0, rule="nonnegative"),
                      static_friction=(f.quantity("static_friction", units[1], rule="nonnegative")
                                       if f.has("static_friction") else None),
                      stribeck_speed=f.quantity("stribeck_speed", units[4], 0.0, rule="nonnegative"))
        require_friction_values(f, values, ("inertia", "coulomb_friction", "stribeck_speed"))
        f.check_unknown()
        return cls(**values)
