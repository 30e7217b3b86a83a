"""Ball screw: screw rotation to nut travel."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..core.fields import Fields, require
from .base import (EFFICIENCY_RANGE, Element, Jet, Lash, Spring, Stage, check_fields, made,
                   read_damping_ratio, read_stroke, screw_backdrive_efficiency)


@dataclass(frozen=True)
class BallScrew(Stage):
    """Ball screw; input = screw angle (rad), output = nut travel (m).

    Parameters
    ----------
    name : str
    lead : float
        Nut travel per screw turn (m); screw angle = 2*pi*x/lead.
    screw_inertia : float
        kg*m^2.
    nut_mass : float
        kg (plus anything rigidly carried by the nut).
    efficiency : float
        Forward power efficiency in (0, 1].
    axial_stiffness : float
        N/m; ``inf`` for rigid.
    backlash : float
        Axial lash of the nut (m).
    dynamic_load_rating : float or None
        Basic dynamic axial load rating C_a of the screw and nut (N, ISO 3408-5): the load
        for a life of 10**6 revolutions; None when not given (no screw life computed).
    bearing_dynamic_load_rating : float or None
        Basic dynamic axial load rating of the screw's axial support bearing (N, ISO 281);
        it carries the screw thrust.
    bearing_kind : str
        ``"ball"`` (life exponent 3) or ``"roller"`` (10/3) bearing.
    damping_ratio : float or None
        Damping ratio of the axial compliance (:mod:`servo_toolkit.drivetrain.chain_damping`);
        None: the model's default structural damping.
    stroke_range : tuple of float or None
        ``[lowest, highest]`` nut travel (m), scene key ``stroke``, when the nut drives the
        output; None: not given (the drivetrain's default stroke applies).
    """

    KIND = "ball_screw"
    IO = ("rotary", "travel")
    UNITS = ("rad", "m", "m")
    RATIO_KEYS = "lead"
    DISPLAY_UNITS = (("backlash", "um", 1e6), ("stroke_range", "mm", 1e3))

    name: str
    lead: float
    screw_inertia: float = 0.0
    nut_mass: float = 0.0
    efficiency: float = 1.0
    axial_stiffness: float = math.inf
    backlash: float = 0.0
    dynamic_load_rating: float | None = None
    bearing_dynamic_load_rating: float | None = None
    bearing_kind: str = "ball"
    damping_ratio: float | None = None
    stroke_range: tuple | None = None

    #: each field's SI unit and rule (:func:`~servo_toolkit.components.base.check_fields`),
    #: checked however the stage is made
    FIELD_RULES = {"lead": ("m/turn", "positive"), "screw_inertia": ("kg*m^2", "nonnegative"),
                   "nut_mass": ("kg", "nonnegative"), "efficiency": ("dimensionless", "efficiency"),
                   "axial_stiffness": ("N/m", "limit"), "backlash": ("m", "nonnegative"),
                   "dynamic_load_rating": ("N", "positive"), "bearing_dynamic_load_rating": ("N", "positive"),
                   "damping_ratio": ("dimensionless", "nonnegative"), "stroke_range": ("m", "stroke")}

    def __post_init__(self):
        check_fields(self, self.FIELD_RULES, "BallScrew")
        require(self.bearing_kind in ("ball", "roller"), "BallScrew.bearing_kind",
                f"must be 'ball' or 'roller' (got {self.bearing_kind!r})")

    @property
    def stroke(self):
        return self.stroke_range

    @property
    def backdrive_efficiency(self) -> float:
        """Back-drive efficiency (:func:`~.base.screw_backdrive_efficiency`)."""
        return screw_backdrive_efficiency(self.efficiency)

    @property
    def ratio(self) -> float:
        """Screw rad per m of nut travel."""
        return 2 * math.pi / self.lead

    def map(self, z) -> Jet:
        return Jet.linear(z, self.ratio)

    def elements(self, z) -> list[Element]:
        return [Element(f"{self.name}: screw", self.screw_inertia, Jet.linear(z, self.ratio), "input"),
                Element(f"{self.name}: nut", self.nut_mass, Jet.linear(z, 1.0))]

    def springs(self, z) -> list[Spring]:
        if math.isinf(self.axial_stiffness):
            return []
        return [Spring(self.name, self.axial_stiffness, Jet.linear(z, 1.0), self.damping_ratio)]

    def lashes(self, z) -> list[Lash]:
        return [Lash(f"{self.name}: nut lash", self.backlash, Jet.linear(z, 1.0))] if self.backlash else []

    @classmethod
    def from_table(cls, f: Fields) -> "BallScrew":
        """Build from a ``[[drivetrain]]`` table of kind ``ball_screw``."""
        stage = made(
            cls, f,
            name=f.text("name", "ball screw"),
            lead=f.quantity("lead", "m/turn", rule="positive", typical=(1e-4, 0.1)),
            screw_inertia=f.quantity("screw_inertia", "kg*m^2", 0.0, rule="nonnegative"),
            nut_mass=f.quantity("nut_mass", "kg", 0.0, rule="nonnegative"),
            efficiency=f.number("efficiency", 1.0, rule="positive", bounds=EFFICIENCY_RANGE),
            axial_stiffness=f.quantity("axial_stiffness", "N/m", math.inf),
            backlash=f.quantity("backlash", "m", 0.0, rule="nonnegative"),
            dynamic_load_rating=(f.quantity("dynamic_load_rating", "N", rule="positive")
                                 if f.has("dynamic_load_rating") else None),
            bearing_dynamic_load_rating=(f.quantity("bearing_dynamic_load_rating", "N", rule="positive")
                                         if f.has("bearing_dynamic_load_rating") else None),
            bearing_kind=f.text("bearing_kind", "ball", choices=("ball", "roller")),
            stroke_range=read_stroke(f, "m", "nut travel"),
        )
        stage = replace(stage, damping_ratio=read_damping_ratio(f, stage.axial_stiffness,
                                                                f.key("axial_stiffness")))
        f.check_unknown()
        return stage
