"""Centred radial cam with a translating roller follower (seed 002)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...core.fields import Fields, require
from ..base import Element, Jet, Lash, Stage, check_fields, made

LAWS = ("modified_constant_velocity",)


def modified_constant_velocity(theta, a: float) -> Jet:
    """Seed 002 cam law: constant velocity with sinusoidal-acceleration transitions.

    Parameters
    ----------
    theta : array_like
        Cam angle (rad), any real value (the law has period 2*pi).
    a : float
        Profile constant A (m); the stroke is 1.5*pi*A.

    Returns
    -------
    Jet
        Follower travel s (m), ds/dtheta (m/rad) and d2s/dtheta2 (m/rad^2).
    """
    th = np.mod(np.asarray(theta, dtype=float), 2 * math.pi)
    q = math.pi / 4
    sin4, cos4 = np.sin(4 * th), np.cos(4 * th)
    trans = th - sin4 / 4  # the sinusoidal-acceleration piece
    conds = [th < q, th < 3 * q, th < 4 * q, th < 5 * q, th < 7 * q]
    s = np.select(conds, [a * trans, 2 * a * th - math.pi * a / 4, math.pi * a / 2 + a * trans,
                          2.5 * math.pi * a - a * trans, 3.75 * math.pi * a - 2 * a * th],
                  2 * math.pi * a - a * trans)
    ds = np.select(conds, [a * (1 - cos4), 2 * a, a * (1 - cos4), -a * (1 - cos4), -2 * a],
                   -a * (1 - cos4))
    d2s = np.select(conds, [4 * a * sin4, 0 * th, 4 * a * sin4, -4 * a * sin4, 0 * th], -4 * a * sin4)
    return Jet(s, ds, d2s)


@dataclass(frozen=True)
class Cam(Stage):
    """Radial cam; a *forward* stage: input = cam angle (rad), output = follower travel (m).

    Parameters
    ----------
    name : str
    law : str
        Cam law name (see ``LAWS``).
    profile_constant : float
        A (m).
    follower_mass : float
        m (kg).
    follower_weight : float
        G (N).
    guide_friction_coefficient : float
        mu of the ball guide.
    gravity_tilt, gravity_heading : float
        gamma and beta of seed 002 eq 3 (rad).
    clearance : float
        Half the cam/roller play c (m).
    base_radius : float
        Pitch base-circle radius r0 (m) of the pressure angle tan(alpha) = (ds/dtheta)/(r0 + s).
        The seed does not print it; 0 means "derive it": the smallest r0 that keeps the
        pressure angle at or below 30 deg (the usual limit for a translating follower),
        see :attr:`pitch_base_radius`.
    """

    KIND = "cam"
    IO = ("rotary", "travel")
    UNITS = ("rad", "m", "m")
    RATIO_KEYS = "profile_constant"
    DISPLAY_UNITS = ()

    name: str
    profile_constant: float
    follower_mass: float
    follower_weight: float = 0.0
    guide_friction_coefficient: float = 0.0
    gravity_tilt: float = 0.0
    gravity_heading: float = 0.0
    clearance: float = 0.0
    law: str = "modified_constant_velocity"
    base_radius: float = 0.0

    #: each field's SI unit and rule (:func:`~servo_toolkit.components.base.check_fields`),
    #: checked however the cam is made
    FIELD_RULES = {"profile_constant": ("m", "positive"), "follower_mass": ("kg", "nonnegative"),
                   "follower_weight": ("N", "nonnegative"),
                   "guide_friction_coefficient": ("dimensionless", "nonnegative"),
                   "gravity_tilt": ("rad", "finite"), "gravity_heading": ("rad", "finite"),
                   "clearance": ("m", "nonnegative"), "base_radius": ("m", "nonnegative")}

    def __post_init__(self):
        check_fields(self, self.FIELD_RULES, "Cam")
        require(self.guide_friction_coefficient < 1, "Cam.guide_friction_coefficient",
                f"must be below 1 (got {self.guide_friction_coefficient:g})")
        require(self.law in LAWS, "Cam.law", f"must be one of {', '.join(LAWS)} (got {self.law!r})")
    direction = "forward"

    @property
    def stroke_length(self) -> float:
        """Follower stroke 1.5*pi*A (m)."""
        return 1.5 * math.pi * self.profile_constant

    @property
    def pitch_base_radius(self) -> float:
        """r0 (m): ``base_radius`` if given, else the smallest radius with alpha <= 30 deg.

        For the conjugate (double-roller) cam both rollers see the same profile half a turn
        apart, so one bound serves both.
        """
        if self.base_radius > 0:
            return self.base_radius
        th = np.linspace(0.0, 2 * math.pi, 4097)
        jet = self.map(th)
        return float(np.max(np.abs(jet.d1) / math.tan(math.radians(30.0)) - jet.value))

    def map(self, z) -> Jet:
        return modified_constant_velocity(z, self.profile_constant)

    def elements(self, z) -> list[Element]:
        return [Element(f"{self.name}: follower", self.follower_mass, self.map(z))]

    def lashes(self, z) -> list[Lash]:
        return [Lash(f"{self.name}: clearance", 2 * self.clearance, self.map(z))] if self.clearance else []

    @classmethod
    def from_table(cls, f: Fields) -> "Cam":
        """Build from a ``[[drivetrain]]`` table of kind ``cam``."""
        cam = made(
            cls, f,
            name=f.text("name", "cam"),
            law=f.text("law", LAWS[0], choices=set(LAWS)),
            profile_constant=f.quantity("profile_constant", "m", rule="positive"),
            follower_mass=f.quantity("follower_mass", "kg", rule="nonnegative"),
            follower_weight=f.quantity("follower_weight", "N", 0.0, rule="nonnegative"),
            guide_friction_coefficient=f.number("guide_friction_coefficient", 0.0, rule="nonnegative"),
            gravity_tilt=f.quantity("gravity_tilt", "rad", 0.0, rule="finite"),
            gravity_heading=f.quantity("gravity_heading", "rad", 0.0, rule="finite"),
            clearance=f.quantity("clearance", "m", 0.0, rule="nonnegative"),
            base_radius=f.quantity("base_radius", "m", 0.0, rule="nonnegative"),
        )
        f.check_unknown()
        return cam
