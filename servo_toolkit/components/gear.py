"""Spur gear train (with idlers)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..core.fields import Fields, require
from ..core.angles import DEG_PER_RAD
from .base import (EFFICIENCY_RANGE, Element, Jet, Lash, Spring, Stage, check_fields, made,
                   read_damping_ratio, read_stroke)


@dataclass(frozen=True)
class GearTrain(Stage):
    """A gear train from the motor side (first gear) to its output shaft (last gear).

    Parameters
    ----------
    name : str
    ratio : float
        Input angle per output angle (``teeth[-1] / teeth[0]``: idlers cancel).
    teeth : tuple of int
        Tooth counts along the train, or empty when only the ratio is known.
    inertias : tuple of float
        Each gear's inertia about its own axis (kg*m^2), in the order of ``teeth``; with no
        teeth, at most two values (input gear, output gear).
    efficiency : float
        Power efficiency in (0, 1].
    torsional_stiffness : float
        Mesh stiffness seen at the output shaft (N*m/rad); ``inf`` for rigid.
    backlash : float
        Total lost motion at the output shaft (rad).
    damping_ratio : float or None
        Damping ratio of the mesh compliance (:mod:`servo_toolkit.drivetrain.chain_damping`);
        None: the model's default structural damping.
    stroke_range : tuple of float or None
        ``[lowest, highest]`` output shaft angle (rad), scene key ``stroke``, when the gear
        drives the output; None: not given (the drivetrain's default stroke applies).
    """

    KIND = "gear"
    IO = ("rotary", "rotary")
    UNITS = ("rad", "rad", "rad")
    RATIO_KEYS = "ratio/teeth"
    DISPLAY_UNITS = (("backlash", "deg", DEG_PER_RAD),)

    name: str
    ratio: float
    teeth: tuple = ()
    inertias: tuple = ()
    efficiency: float = 1.0
    torsional_stiffness: float = math.inf
    backlash: float = 0.0
    damping_ratio: float | None = None
    stroke_range: tuple | None = None

    #: each field's SI unit and rule (:func:`~servo_toolkit.components.base.check_fields`),
    #: checked however the stage is made
    FIELD_RULES = {"ratio": ("dimensionless", "positive"), "inertias": ("kg*m^2", "nonnegative"),
                   "efficiency": ("dimensionless", "efficiency"), "torsional_stiffness": ("N*m/rad", "limit"),
                   "backlash": ("rad", "nonnegative"), "damping_ratio": ("dimensionless", "nonnegative"),
                   "stroke_range": ("rad", "stroke")}

    def __post_init__(self):
        check_fields(self, self.FIELD_RULES, "GearTrain")

    @property
    def stroke(self):
        return self.stroke_range

    def _speed_ratios(self) -> list[float]:
        """Each gear's angle per output angle."""
        if self.teeth:
            return [self.teeth[-1] / z for z in self.teeth]
        return [self.ratio, 1.0][: len(self.inertias)]

    def map(self, z) -> Jet:
        return Jet.linear(z, self.ratio)

    def elements(self, z) -> list[Element]:
        # the first gear turns with the input shaft: motor side of the mesh spring
        return [Element(f"{self.name}: gear {i + 1}", j, Jet.linear(z, g), "input" if i == 0 else "output")
                for i, (j, g) in enumerate(zip(self.inertias, self._speed_ratios()))]

    def springs(self, z) -> list[Spring]:
        if math.isinf(self.torsional_stiffness):
            return []
        return [Spring(self.name, self.torsional_stiffness, Jet.linear(z, 1.0), self.damping_ratio)]

    def lashes(self, z) -> list[Lash]:
        return [Lash(f"{self.name}: backlash", self.backlash, Jet.linear(z, 1.0))] if self.backlash else []

    @classmethod
    def from_table(cls, f: Fields) -> "GearTrain":
        """Build from a ``[[drivetrain]]`` table of kind ``gear``."""
        raw = f.raw("teeth", ())
        require(isinstance(raw, (list, tuple)), f.key("teeth"),
                f"expected a list of tooth counts along the train, e.g. [24, 40], got {raw!r}")
        teeth = tuple(raw)
        for i, z in enumerate(teeth):
            require(isinstance(z, int) and not isinstance(z, bool) and z > 0,
                    f"{f.key('teeth')}[{i}]", f"tooth count must be a positive integer (got {z!r})")
        if teeth:
            require(len(teeth) >= 2, f.key("teeth"), "a gear train needs at least two gears")
            require(not f.has("ratio"), f.key("ratio"), "give either teeth or ratio, not both")
            ratio = teeth[-1] / teeth[0]
        else:
            ratio = f.quantity("ratio", "dimensionless", rule="positive")
        inertias = f.quantity_list("inertia", "kg*m^2", (), rule="nonnegative")
        if teeth:
            require(len(inertias) in (0, len(teeth)), f.key("inertia"),
                    f"give one inertia per gear ({len(teeth)}), got {len(inertias)}")
        else:
            require(len(inertias) <= 2, f.key("inertia"), "with a ratio only, give at most [input, output]")
        stage = made(
            cls, f, name=f.text("name", "gear train"), ratio=ratio, teeth=teeth, inertias=inertias,
            efficiency=f.number("efficiency", 1.0, rule="positive", bounds=EFFICIENCY_RANGE),
            torsional_stiffness=f.quantity("torsional_stiffness", "N*m/rad", math.inf),
            backlash=f.quantity("backlash", "rad", 0.0, rule="nonnegative"),
            stroke_range=read_stroke(f, "rad", "output angle"),
        )
        stage = replace(stage, damping_ratio=read_damping_ratio(f, stage.torsional_stiffness,
                                                                f.key("torsional_stiffness")))
        f.check_unknown()
        return stage
