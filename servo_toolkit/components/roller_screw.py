"""Planetary roller screw stages (seed 004): description and validation."""

from __future__ import annotations

from dataclasses import dataclass

from ..fields import Fields, require


@dataclass(frozen=True)
class RollerScrewStage:
    """One stage of a multi-stage planetary roller screw, SI units.

    Radii in m, masses in kg, inertias in kg*m^2, angles in rad. ``screw_spline_radius``
    (r_SS) and ``nut_screw_joint_radius`` (r_NS) belong to stages after the first.
    """

    screw_radius: float
    roller_radius: float
    nut_radius: float
    screw_starts: int
    lead: float
    flank_angle: float
    ring_gear_pressure_angle: float
    rollers: int
    roller_mass: float
    nut_mass: float
    screw_inertia: float
    roller_inertia: float
    carrier_inertia: float
    screw_mass: float = 0.0
    screw_spline_radius: float = 0.0
    nut_screw_joint_radius: float = 0.0

    @classmethod
    def from_table(cls, f: Fields, first: bool) -> "RollerScrewStage":
        """Build from one ``[[stages]]`` table."""
        q = f.quantity

        def joint(name):
            # joints to the previous stage: required on every stage after the first
            return q(name, "m", 0.0, rule="nonnegative") if first else q(name, "m", rule="positive")

        stage = cls(
            screw_radius=q("screw_radius", "m", rule="positive"),
            roller_radius=q("roller_radius", "m", rule="positive"),
            nut_radius=q("nut_radius", "m", rule="positive"),
            screw_starts=f.integer("screw_starts", minimum=1),
            lead=q("lead", "m", rule="positive"),
            flank_angle=q("flank_angle", "rad", rule="positive"),
            ring_gear_pressure_angle=q("ring_gear_pressure_angle", "rad", rule="positive"),
            rollers=f.integer("rollers", minimum=1),
            roller_mass=q("roller_mass", "kg", rule="nonnegative"),
            nut_mass=q("nut_mass", "kg", rule="nonnegative"),
            screw_inertia=q("screw_inertia", "kg*m^2", rule="nonnegative"),
            roller_inertia=q("roller_inertia", "kg*m^2", rule="nonnegative"),
            carrier_inertia=q("carrier_inertia", "kg*m^2", rule="nonnegative"),
            screw_mass=q("screw_mass", "kg", 0.0, rule="nonnegative"),
            screw_spline_radius=joint("screw_spline_radius"),
            nut_screw_joint_radius=joint("nut_screw_joint_radius"),
        )
        require(abs(stage.nut_radius - stage.screw_radius - 2 * stage.roller_radius)
                <= 1e-3 * stage.nut_radius, f.key("nut_radius"),
                "nut pitch radius must equal screw radius + 2 * roller radius")
        f.check_unknown()
        return stage


@dataclass(frozen=True)
class RollerScrewOperating:
    """Operating point of a roller-screw scene (``[operating]``)."""

    screw_speed: float
    load: float
    roller_screw_friction: float
    screw_screw_friction: tuple
    nut_screw_friction: tuple

    @classmethod
    def from_table(cls, f: Fields) -> "RollerScrewOperating":
        """Build from an ``[operating]`` table."""
        def coefficients(name):
            raw = f.raw(name, [0.0])
            values = raw if isinstance(raw, list) else [raw]
            return tuple(_coefficient(v, f"{f.key(name)}[{i}]") for i, v in enumerate(values))
        op = cls(screw_speed=f.quantity("screw_speed", "rad/s", rule="finite"),
                 load=f.quantity("load", "N", rule="finite"),
                 roller_screw_friction=_coefficient(f.raw("roller_screw_friction", 0.0),
                                                    f.key("roller_screw_friction")),
                 screw_screw_friction=coefficients("screw_screw_friction"),
                 nut_screw_friction=coefficients("nut_screw_friction"))
        f.check_unknown()
        return op


def _coefficient(value, key: str) -> float:
    require(isinstance(value, (int, float)) and not isinstance(value, bool), key,
            f"friction coefficient must be a number (got {value!r})")
    require(0 <= value < 1, key, f"friction coefficient must be in [0, 1) (got {value})")
    return float(value)
