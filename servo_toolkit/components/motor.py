"""Permanent-magnet DC motor."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..core.fields import Fields, field_value, require


#: Kt (N*m/A) and Ke (V*s/rad) of a DC motor are one constant in SI (the power balance
#: Kt i w = Ke w i); datasheet values may differ by a few percent (losses, rounding; the cam
#: follower's motor gives 0.1471 and 0.146), by more than this relative amount they are a
#: unit slip
KT_KE_TOLERANCE = 0.10
#: (factor, likely slip) of the usual unit slips between Kt and Ke
_SLIPS = ((1000.0, "a milli prefix dropped or added (mV*s/rad, mN*m/A)"),
          (1000 * 2 * math.pi / 60, "Ke per 1000 rpm (V/krpm) given as V*s/rad"),
          (60 / (2 * math.pi), "Ke per rpm (V/rpm) given as V*s/rad, or rpm taken for rad/s"),
          (2 * math.pi, "per revolution taken for per radian"),
          (9.80665, "kgf*m/A taken for N*m/A"))


def kt_ke_rule(kt: float, ke: float) -> str:
    """The rule broken by a Kt/Ke pair more than :data:`KT_KE_TOLERANCE` apart, with the
    likely slip; "" when they agree."""
    if abs(kt - ke) <= KT_KE_TOLERANCE * max(kt, ke):
        return ""
    ratio = kt / ke
    big = max(ratio, 1 / ratio)
    guess = next((f": likely {what}" for factor, what in _SLIPS if abs(big / factor - 1) <= KT_KE_TOLERANCE), "")
    return (f"must equal torque_constant within {KT_KE_TOLERANCE:.0%}: a DC motor's Kt in N*m/A and Ke in "
            f"V*s/rad are the same constant in SI (got Kt = {kt:g} N*m/A, Ke = {ke:g} V*s/rad, Ke "
            f"{'smaller' if ratio > 1 else 'larger'} by a factor of {big:.4g}{guess})")


#: largest value of each motor constant the models are conditioned for (SI): far beyond any
#: electric motor (a 1 MW machine has Kt of a few hundred N*m/A)
PLAUSIBLE_MAX = {"resistance": 1e15, "inductance": 10.0, "torque_constant": 1e4, "back_emf_constant": 1e4,
                 "rotor_inertia": 1e4, "viscous_friction": 1e6, "coulomb_friction": 1e6}


#: shortest electrical time constant L/R a motor with inductance may have (s): the stiff
#: reference solver stalls on the armature's mode below about 1e-8 s with the reference EMA's
#: 0.1 ms controller sample; every electric motor's is above 1e-5 s
MIN_ELECTRICAL_TIME_CONSTANT = 1e-7


#: the values a DC servo motor's catalogue keys take, from a 10 mm coreless motor to a
#: 10 kW servo (SI; a third element the unit a slip is most likely meant in): a bare number
#: outside them loads with a note naming the SI unit it was read in
TYPICAL = {"resistance": (1e-3, 200.0), "torque_constant": (1e-3, 10.0), "back_emf_constant": (1e-3, 10.0),
           "rotor_inertia": (1e-9, 0.05, "g*cm^2"), "viscous_friction": (1e-9, 0.1),
           "coulomb_friction": (1e-5, 10.0), "voltage_limit": (1.0, 1000.0), "current_limit": (0.01, 1000.0)}


#: each field's SI unit and sign rule (:func:`~servo_toolkit.core.fields.check_rule`), checked
#: however a motor is made (the scene file, ``dataclasses.replace``); the file's stricter
#: rules (a rotor inertia and a back EMF above 0, plausible magnitudes, Kt = Ke) are the
#: loader's (a model may leave the back EMF out, as the chain's modal tests do)
FIELD_RULES = {"resistance": ("ohm", "positive"), "inductance": ("H", "nonnegative"),
               "torque_constant": ("N*m/A", "positive"), "back_emf_constant": ("V*s/rad", "nonnegative"),
               "rotor_inertia": ("kg*m^2", "nonnegative"), "viscous_friction": ("N*m*s/rad", "nonnegative"),
               "coulomb_friction": ("N*m", "nonnegative"), "voltage_limit": ("V", "limit"),
               "current_limit": ("A", "limit"), "static_friction": ("N*m", "nonnegative"),
               "stribeck_speed": ("rad/s", "nonnegative"), "continuous_torque": ("N*m", "positive"),
               "peak_torque": ("N*m", "positive"), "thermal_resistance_winding": ("K/W", "positive"),
               "thermal_resistance_housing": ("K/W", "positive"), "thermal_time_constant_winding": ("s", "positive"),
               "thermal_time_constant_housing": ("s", "positive"), "max_winding_temperature": ("K", "positive"),
               "ambient_temperature": ("K", "positive"), "resistance_temperature": ("K", "positive"),
               "copper_temperature_coefficient": ("1/K", "nonnegative")}
#: the fields that may be None (not given)
OPTIONAL_FIELDS = ("static_friction", "continuous_torque", "peak_torque", "thermal_resistance_winding",
                   "thermal_resistance_housing", "thermal_time_constant_winding", "thermal_time_constant_housing")


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
    static_friction : float or None
        Breakaway torque Ts >= Tc (N*m); None: Ts = Tc (Coulomb friction that holds up to
        its own level).
    stribeck_speed : float
        Speed w_st (rad/s) over which the friction falls from Ts to Tc,
        Tc + (Ts - Tc) exp(-(w / w_st)^2); 0: at once.
    continuous_torque, peak_torque : float or None
        Datasheet continuous (stall) and peak torque (N*m); None when not given (the sizing
        then takes the peak from the current limit and the continuous from the thermal
        network).
    thermal_resistance_winding, thermal_resistance_housing : float or None
        Two-node thermal network: winding to housing and housing to ambient (K/W).
    thermal_time_constant_winding, thermal_time_constant_housing : float or None
        R*C of each node (s): the winding's with the winding-to-housing resistance, the
        housing's with the housing-to-ambient one.
    max_winding_temperature : float
        Insulation limit of the winding (K; scenes write e.g. ``"155 degC"``).
    ambient_temperature : float
        K.
    resistance_temperature : float
        Winding temperature at which ``resistance`` is given (K).
    copper_temperature_coefficient : float
        Rise of the winding resistance per kelvin (1/K; copper 0.00393).
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
    static_friction: float | None = None
    stribeck_speed: float = 0.0

    continuous_torque: float | None = None
    peak_torque: float | None = None
    thermal_resistance_winding: float | None = None
    thermal_resistance_housing: float | None = None
    thermal_time_constant_winding: float | None = None
    thermal_time_constant_housing: float | None = None
    max_winding_temperature: float = 428.15
    ambient_temperature: float = 298.15
    resistance_temperature: float = 298.15
    copper_temperature_coefficient: float = 0.00393

    def __post_init__(self):
        for name, (unit, rule) in FIELD_RULES.items():
            value = getattr(self, name)
            if value is not None or name not in OPTIONAL_FIELDS:
                object.__setattr__(self, name, field_value(value, unit, rule, f"motor.{name}"))

    @property
    def breakaway_torque(self) -> float:
        """Ts: the static friction, or the Coulomb friction where none is given (N*m)."""
        return self.coulomb_friction if self.static_friction is None else self.static_friction

    @property
    def has_thermal_network(self) -> bool:
        """True when the scene gives the four values of the two-node thermal network."""
        return None not in (self.thermal_resistance_winding, self.thermal_resistance_housing,
                            self.thermal_time_constant_winding, self.thermal_time_constant_housing)

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
            resistance=f.quantity("resistance", "ohm", rule="positive", typical=TYPICAL["resistance"]),
            inductance=f.quantity("inductance", "H", 0.0, rule="nonnegative", typical=(1e-6, 0.5)),
            torque_constant=f.quantity("torque_constant", "N*m/A", rule="positive", typical=TYPICAL["torque_constant"]),
            back_emf_constant=f.quantity("back_emf_constant", "V*s/rad", rule="positive",
                                         typical=TYPICAL["back_emf_constant"]),
            rotor_inertia=f.quantity("rotor_inertia", "kg*m^2", rule="positive", typical=TYPICAL["rotor_inertia"]),
            viscous_friction=f.quantity("viscous_friction", "N*m*s/rad", 0.0, rule="nonnegative",
                                        typical=TYPICAL["viscous_friction"]),
            coulomb_friction=f.quantity("coulomb_friction", "N*m", 0.0, rule="nonnegative",
                                        typical=TYPICAL["coulomb_friction"]),
            voltage_limit=f.quantity("voltage_limit", "V", math.inf, typical=TYPICAL["voltage_limit"]),
            current_limit=f.quantity("current_limit", "A", math.inf, typical=TYPICAL["current_limit"]),
            static_friction=(f.quantity("static_friction", "N*m", rule="nonnegative")
                             if f.has("static_friction") else None),
            stribeck_speed=f.quantity("stribeck_speed", "rad/s", 0.0, rule="nonnegative"),
            **_sizing_keys(f),
        )
        for key, top in PLAUSIBLE_MAX.items():  # beyond these the plant's matrices lose their digits
            value = getattr(motor, key)
            require(value <= top, f.key(key), f"must be at most {top:g} (got {value:g}): outside the range "
                    "of electric motors the models are conditioned for")
        rule = kt_ke_rule(motor.torque_constant, motor.back_emf_constant)
        require(not rule, f.key("back_emf_constant"), rule)
        require(motor.resistance >= 1e-6, f.key("resistance"), f"must be at least 1e-06 ohm (got {motor.resistance:g})")
        tau = motor.electrical_time_constant
        require(motor.inductance == 0 or tau >= MIN_ELECTRICAL_TIME_CONSTANT, f.key("inductance"),
                f"with the resistance {motor.resistance:g} ohm, L/R = {tau:.3g} s is below "
                f"{MIN_ELECTRICAL_TIME_CONSTANT:g} s, the shortest electrical time constant the solvers are "
                "conditioned for (a motor's is 1e-5 s or more); give 0 H to neglect the inductance "
                f"(got {motor.inductance:g} H)")
        require(motor.breakaway_torque >= motor.coulomb_friction, f.key("static_friction"),
                f"must be at least the coulomb_friction {motor.coulomb_friction:g} N*m (got {motor.breakaway_torque:g})")
        require(motor.breakaway_torque <= PLAUSIBLE_MAX["coulomb_friction"], f.key("static_friction"),
                f"must be at most {PLAUSIBLE_MAX['coulomb_friction']:g} N*m (got {motor.breakaway_torque:g})")
        require(math.isfinite(motor.stribeck_speed), f.key("stribeck_speed"), "must be finite")
        require(motor.voltage_limit > 0, f.key("voltage_limit"), "must be positive")
        require(motor.current_limit > 0, f.key("current_limit"), "must be positive")
        _check_thermal(motor, f)
        f.check_unknown()
        return motor


#: optional sizing keys of ``[motor]``: name -> (unit, rule)
_OPTIONAL = {"continuous_torque": ("N*m", "positive"), "peak_torque": ("N*m", "positive"),
             "thermal_resistance_winding": ("K/W", "positive"), "thermal_resistance_housing": ("K/W", "positive"),
             "thermal_time_constant_winding": ("s", "positive"), "thermal_time_constant_housing": ("s", "positive")}


def _sizing_keys(f: Fields) -> dict:
    """The optional sizing values of a ``[motor]`` table (datasheet torques, thermal network)."""
    out = {k: f.quantity(k, unit, rule=rule) for k, (unit, rule) in _OPTIONAL.items() if f.has(k)}
    out["max_winding_temperature"] = f.quantity("max_winding_temperature", "K", 428.15, rule="positive")
    out["ambient_temperature"] = f.quantity("ambient_temperature", "K", 298.15, rule="positive")
    out["resistance_temperature"] = f.quantity("resistance_temperature", "K", 298.15, rule="positive")
    out["copper_temperature_coefficient"] = f.quantity("copper_temperature_coefficient", "1/K", 0.00393,
                                                       rule="nonnegative")
    return out


def _check_thermal(motor: DCMotor, f: Fields) -> None:
    """The thermal network is given whole or not at all, and its limits are physical."""
    given = [k for k in _OPTIONAL if k.startswith("thermal_") and getattr(motor, k) is not None]
    missing = [k for k in _OPTIONAL if k.startswith("thermal_") and getattr(motor, k) is None]
    require(not given or not missing, f.key(missing[0] if missing else ""),
            f"missing key: the two-node thermal network needs all four of its values (got {given})")
    require(motor.max_winding_temperature > motor.ambient_temperature, f.key("max_winding_temperature"),
            f"must be above the ambient temperature ({motor.ambient_temperature - 273.15:g} degC)")
    require(motor.copper_temperature_coefficient <= 0.1, f.key("copper_temperature_coefficient"),
            f"must be at most 0.1 1/K (got {motor.copper_temperature_coefficient:g}; copper is 0.00393)")
    if motor.continuous_torque is not None and motor.peak_torque is not None:
        require(motor.peak_torque >= motor.continuous_torque, f.key("peak_torque"),
                f"must be at least continuous_torque ({motor.continuous_torque:g} N*m)")
