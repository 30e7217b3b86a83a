"""Rocker linkage: nut pin A on the screw axis, link rod AB, rocker arm OB on the output shaft.

Geometry (DESIGN.md): B = (r sin phi, r cos phi), the screw axis is y = h with
h = r + rod_offset, A = (x_A, h) behind the arm, |AB| = l, so

    x_A(phi) = r sin(phi) - sqrt(l^2 - (h - r cos(phi))^2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..core.fields import Fields, require
from ..errors import SceneError
from .base import Element, Jet, Spring, Stage, check_fields, made, read_damping_ratio


@dataclass(frozen=True)
class RockerLinkage(Stage):
    """Link rod and rocker arm; input = nut travel x_A (m), output = shaft angle phi (rad).

    Parameters
    ----------
    name : str
    arm_length, rod_length, rod_offset : float
        r, l and h - r (m).
    rod_mass : float
        kg; the rod is a uniform bar condensed to its two ends plus a rotary correction
        (-m l^2/6 about its own angle) so that its inertia equals the bar's m l^2/12.
    output_shaft_mass, output_shaft_inertia : float
        kg and kg*m^2 (the mass does not enter the rotation).
    rod_axial_stiffness : float
        N/m along AB; ``inf`` for rigid.
    stroke : tuple of float
        (min, max) output angle (rad).
    damping_ratio : float or None
        Damping ratio of the rod's axial compliance
        (:mod:`servo_toolkit.drivetrain.chain_damping`); None: the model's default.
    """

    KIND = "rocker_linkage"
    IO = ("travel", "rotary")
    UNITS = ("m", "rad", "m")
    RATIO_KEYS = "arm_length, rod_length"
    DISPLAY_UNITS = ()

    name: str
    arm_length: float
    rod_length: float
    rod_offset: float = 0.0
    rod_mass: float = 0.0
    output_shaft_mass: float = 0.0
    output_shaft_inertia: float = 0.0
    rod_axial_stiffness: float = math.inf
    stroke_range: tuple = (-math.pi / 6, math.pi / 6)
    efficiency: float = 1.0
    damping_ratio: float | None = None

    #: each field's SI unit and rule (:func:`~servo_toolkit.components.base.check_fields`),
    #: checked however the stage is made
    FIELD_RULES = {"arm_length": ("m", "positive"), "rod_length": ("m", "positive"), "rod_offset": ("m", "finite"),
                   "rod_mass": ("kg", "nonnegative"), "output_shaft_mass": ("kg", "nonnegative"),
                   "output_shaft_inertia": ("kg*m^2", "nonnegative"), "rod_axial_stiffness": ("N/m", "limit"),
                   "stroke_range": ("rad", "stroke"), "efficiency": ("dimensionless", "efficiency"),
                   "damping_ratio": ("dimensionless", "nonnegative")}

    def __post_init__(self):
        check_fields(self, self.FIELD_RULES, "RockerLinkage")
        broken = self.geometry_rule()
        if broken is not None:
            raise SceneError(f"RockerLinkage.{broken[0]}", broken[1])

    def geometry_rule(self) -> tuple | None:
        """``(field, rule)`` of the geometry's first broken rule, None when it holds: each
        end of the stroke within (-180, 180) deg of the arm's reference position, a rod
        longer than the stroke needs, no dead point inside the stroke."""
        lo, hi = self.stroke_range
        if not (abs(lo) < math.pi and abs(hi) < math.pi):
            return "stroke_range", "each end must lie within (-180, 180) deg of the arm's reference position"
        phi = np.linspace(lo, hi, 721)
        w, _, _ = self._w(phi)
        need = float(np.max(np.abs(w)))
        if not self.rod_length > need * 1.0001:
            return "rod_length", (f"rod too short for the geometry: the stroke needs l > |h - r cos(phi)| = "
                                  f"{need * 1e3:.3f} mm (got {self.rod_length * 1e3:.3f} mm)")
        if not bool(np.all(self.map(phi).d1 > 0)):
            return "stroke_range", "the linkage passes a dead point (dx_A/dphi <= 0) inside the stroke"
        return None

    @property
    def stroke(self):
        return self.stroke_range

    def _w(self, phi):
        r, h = self.arm_length, self.arm_length + self.rod_offset
        return h - r * np.cos(phi), r * np.sin(phi), r * np.cos(phi)

    def map(self, z) -> Jet:
        phi = np.asarray(z, dtype=float)
        r, l = self.arm_length, self.rod_length
        w, w1, w2 = self._w(phi)
        d = np.sqrt(l**2 - w**2)
        d1 = -w * w1 / d
        d2 = -(w1**2 + w * w2) / d - (w * w1) ** 2 / d**3
        return Jet(r * np.sin(phi) - d, r * np.cos(phi) - d1, -r * np.sin(phi) - d2)

    def rod_angle(self, z) -> Jet:
        """Angle psi of the rod against the screw axis, sin(psi) = (h - r cos phi)/l."""
        w, w1, w2 = self._w(np.asarray(z, dtype=float))
        l = self.rod_length
        s, s1, s2 = w / l, w1 / l, w2 / l
        c = np.sqrt(1 - s**2)
        return Jet(np.arcsin(s), s1 / c, s2 / c + s * s1**2 / c**3)

    def rod_stretch_rate(self, z) -> np.ndarray:
        """d|AB|/dphi at fixed A: (B - A) . dB/dphi / l (m/rad)."""
        phi = np.asarray(z, dtype=float)
        r, l = self.arm_length, self.rod_length
        w, w1, _ = self._w(phi)
        d = np.sqrt(l**2 - w**2)
        return (d * r * np.cos(phi) + w * w1) / l

    def elements(self, z) -> list[Element]:
        m, r, l = self.rod_mass, self.arm_length, self.rod_length
        return [
            Element(f"{self.name}: output shaft", self.output_shaft_inertia, Jet.linear(z, 1.0)),
            Element(f"{self.name}: rod end at nut", m / 2, self.map(z), "input"),
            Element(f"{self.name}: rod end at arm", m / 2, Jet.linear(z, r)),
            Element(f"{self.name}: rod rotation", -m * l**2 / 6, self.rod_angle(z)),
        ]

    def springs(self, z) -> list[Spring]:
        if math.isinf(self.rod_axial_stiffness):
            return []
        rate = self.rod_stretch_rate(z)
        return [Spring(self.name, self.rod_axial_stiffness,
                       Jet(np.zeros_like(rate), rate, np.zeros_like(rate)), self.damping_ratio)]

    @classmethod
    def from_table(cls, f: Fields) -> "RockerLinkage":
        """Build from a ``[[drivetrain]]`` table of kind ``rocker_linkage``."""
        stroke = f.quantity_list("stroke", "rad", (-math.pi / 6, math.pi / 6), rule="finite")
        require(len(stroke) == 2 and stroke[0] < stroke[1], f.key("stroke"),
                "must be [min, max] with min < max")
        stage = made(
            cls, f,
            name=f.text("name", "rocker linkage"),
            arm_length=f.quantity("arm_length", "m", rule="positive"),
            rod_length=f.quantity("rod_length", "m", rule="positive"),
            rod_offset=f.quantity("rod_offset", "m", 0.0, rule="finite"),
            rod_mass=f.quantity("rod_mass", "kg", 0.0, rule="nonnegative"),
            output_shaft_mass=f.quantity("output_shaft_mass", "kg", 0.0, rule="nonnegative"),
            output_shaft_inertia=f.quantity("output_shaft_inertia", "kg*m^2", 0.0, rule="nonnegative"),
            rod_axial_stiffness=f.quantity("rod_axial_stiffness", "N/m", math.inf),
            stroke_range=tuple(stroke),
        )
        stage = replace(stage, damping_ratio=read_damping_ratio(f, stage.rod_axial_stiffness,
                                                                f.key("rod_axial_stiffness")))
        f.check_unknown()
        return stage
