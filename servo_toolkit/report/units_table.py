"""Display units for the scene summary: SI floats inside, engineering units in the report."""

from __future__ import annotations

import dataclasses

from ..display.units import DIMENSIONLESS
from ..core.angles import DEG_PER_RAD


#: field name -> (display unit, factor from SI)
UNITS = {
    "resistance": ("ohm", 1.0), "inductance": ("mH", 1e3), "torque_constant": ("N*m/A", 1.0),
    "back_emf_constant": ("V*s/rad", 1.0), "rotor_inertia": ("kg*m^2", 1.0),
    "viscous_friction": ("N*m*s/rad", 1.0), "coulomb_friction": ("N*m", 1.0),
    "voltage_limit": ("V", 1.0), "current_limit": ("A", 1.0),
    "ratio": (DIMENSIONLESS, 1.0), "teeth": (DIMENSIONLESS, 1.0), "inertias": ("kg*m^2", 1.0), "efficiency": (DIMENSIONLESS, 1.0),
    "torsional_stiffness": ("N*m/rad", 1.0), "lead": ("mm", 1e3), "screw_inertia": ("kg*m^2", 1.0),
    "nut_mass": ("kg", 1.0), "axial_stiffness": ("N/m", 1.0), "arm_length": ("mm", 1e3),
    "rod_length": ("mm", 1e3), "rod_offset": ("mm", 1e3), "rod_mass": ("kg", 1.0),
    "output_shaft_mass": ("kg", 1.0), "output_shaft_inertia": ("kg*m^2", 1.0),
    "rod_axial_stiffness": ("N/m", 1.0), "stroke_range": ("deg", DEG_PER_RAD), "stroke": ("deg", DEG_PER_RAD),
    "stiffness": ("N*m/rad", 1.0), "inertia": ("kg*m^2", 1.0), "hinge_moment": ("N*m", 1.0),
    "hinge_stiffness": ("N*m/rad", 1.0), "damping": ("N*m*s/rad", 1.0),
    "profile_constant": ("mm", 1e3), "follower_mass": ("kg", 1.0), "follower_weight": ("N", 1.0),
    "guide_friction_coefficient": (DIMENSIONLESS, 1.0), "gravity_tilt": ("deg", DEG_PER_RAD),
    "gravity_heading": ("deg", DEG_PER_RAD), "clearance": ("mm", 1e3),
    "output_encoder_bits": ("bit", 1.0), "output_scale_resolution": ("um", 1e6), "motor_encoder_counts": ("counts/rev", 1.0),
    "sample_time": ("ms", 1e3), "bandwidth": ("Hz", 1.0), "max_phase_lag_at_bandwidth": ("deg", DEG_PER_RAD),
    "min_gain_margin": ("dB", 1.0), "min_phase_margin": ("deg", DEG_PER_RAD), "max_sensitivity_peak": ("dB", 1.0),
    "screw_radius": ("mm", 1e3), "roller_radius": ("mm", 1e3), "nut_radius": ("mm", 1e3),
    "screw_spline_radius": ("mm", 1e3), "nut_screw_joint_radius": ("mm", 1e3),
    "screw_starts": (DIMENSIONLESS, 1.0), "rollers": (DIMENSIONLESS, 1.0), "flank_angle": ("deg", DEG_PER_RAD),
    "ring_gear_pressure_angle": ("deg", DEG_PER_RAD), "roller_mass": ("kg", 1.0), "screw_mass": ("kg", 1.0),
    "roller_inertia": ("kg*m^2", 1.0), "carrier_inertia": ("kg*m^2", 1.0),
    "screw_speed": ("rad/s", 1.0), "load": ("N", 1.0), "roller_screw_friction": (DIMENSIONLESS, 1.0),
    "screw_screw_friction": (DIMENSIONLESS, 1.0), "nut_screw_friction": (DIMENSIONLESS, 1.0),
    "ratio_x": (DIMENSIONLESS, 1.0), "ratio_y": (DIMENSIONLESS, 1.0), "platform_inertia": ("kg*m^2", 1.0),
    "static_friction": ("N*m", 1.0), "stribeck_speed": ("rad/s", 1.0), "base_radius": ("mm", 1e3),
    "thermal_resistance_winding": ("K/W", 1.0), "thermal_resistance_housing": ("K/W", 1.0),
    "thermal_time_constant_winding": ("s", 1.0), "thermal_time_constant_housing": ("s", 1.0),
    "copper_temperature_coefficient": ("1/K", 1.0), "dynamic_load_rating": ("N", 1.0),
    "static_load_rating": ("N", 1.0), "bearing_dynamic_load_rating": ("N", 1.0),
}
#: temperatures (K inside) shown in degC
TEMPERATURES = {"max_winding_temperature", "ambient_temperature", "resistance_temperature"}
#: the time requirements' fields other than positions (:mod:`servo_toolkit.scene.time_requirements`)
TIME_UNITS = {"max_overshoot": ("%", 100.0), "max_settling_time": ("ms", 1e3), "max_current_ripple": ("A", 1.0),
              "max_rms_current": ("A", 1.0), "max_time_at_current_limit": ("ms", 1e3),
              "max_time_at_voltage_limit": ("ms", 1e3)}
#: (class name, field) overrides where one name means different quantities
_SKIP = {"name", "direction"}


def _scaled(value, factor):
    if isinstance(value, (list, tuple)):
        return [_scaled(v, factor) for v in value]
    if hasattr(value, "tolist"):
        return _scaled(value.tolist(), factor)
    if isinstance(value, dict):
        return {k: _scaled(v, factor) for k, v in value.items()}
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return value
    return value * factor


def _text(value) -> str:
    from .section import fmt
    if isinstance(value, list):
        return "[" + ", ".join(_text(v) for v in value) + "]"
    if isinstance(value, dict):
        return ", ".join(f"{k}: {_text(v)}" for k, v in value.items())
    return fmt(value, 5)


#: the load of an output travel (a chain ending in a screw): a mass and forces
LINEAR_LOAD = {"inertia": ("kg", 1.0), "hinge_moment": ("N", 1.0), "hinge_stiffness": ("N/m", 1.0),
               "damping": ("N*s/m", 1.0), "coulomb_friction": ("N", 1.0), "static_friction": ("N", 1.0),
               "stribeck_speed": ("m/s", 1.0)}


def rows(obj, units: dict | None = None) -> list[tuple[str, str, str]]:
    """(field, value, unit) rows of a frozen dataclass, values in display units.

    Fields without a known unit are shown in SI with the unit ``SI``; ``units`` (field ->
    (unit, factor from SI)) takes precedence, e.g. :data:`LINEAR_LOAD`.
    """
    out = []
    overrides = {name: (unit, factor) for name, unit, factor in getattr(obj, "DISPLAY_UNITS", ())}
    for f in dataclasses.fields(obj):
        if f.name in _SKIP or f.name.startswith("_"):
            continue
        value = getattr(obj, f.name)
        if value is None:
            continue
        if isinstance(value, (list, tuple)) and value and all(dataclasses.is_dataclass(v) for v in value):
            # nested parts (a roller screw's stages): each field on its own row, in its unit
            out += [(f"{f.name}[{i}].{name}", text, unit) for i, v in enumerate(value) for name, text, unit in rows(v)]
            continue
        if dataclasses.is_dataclass(value) and hasattr(value, "dimensions"):
            # the time requirements: each key the scene set, a position as an angle or a length
            lengths = {k for k, d in value.dimensions if d == "length"}
            units = {k: (("mm", 1e3) if k in lengths else ("deg", DEG_PER_RAD)) for k in value.given()} | TIME_UNITS
            out += [(f"{f.name}.{name}", text, unit) for name, text, unit in rows(value, units)
                    if name != "dimensions"]
            continue
        if f.name in TEMPERATURES and isinstance(value, (int, float)):
            out.append((f.name, _text(value - 273.15), "degC"))
            continue
        unit, factor = (units or {}).get(f.name) or overrides.get(f.name, UNITS.get(f.name, ("SI", 1.0)))
        if isinstance(value, str):
            unit = ""
        out.append((f.name, _text(_scaled(value, factor)), unit))
    return out
