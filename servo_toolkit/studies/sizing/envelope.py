"""The motor's torque-speed envelope and the margins of a sizing.

Envelope of a DC motor on a supply of voltage V with a current limit I:

* peak torque: the datasheet ``peak_torque``, and at most Kt I;
* continuous torque: the datasheet ``continuous_torque``, else the stall torque the thermal
  network allows: Kt sqrt((T_max - T_a) / ((R_wh + R_ha) R(T_max))) (none without either);
* voltage line: the torque the supply can push at speed w, Kt (V - Ke |w|) / R(T_max), zero
  at the no-load speed V / Ke. The winding is taken hot (at its limit T_max) for every
  voltage figure, the conservative side. Braking (torque against the speed), the back-EMF
  helps the supply: |u| = |R i - Ke w| <= V allows up to Kt (V + Ke |w|) / R(T_max).

A margin is the distance to the limit as a fraction of it: 1 - value / limit for an upper
limit (torque, current, voltage, temperature rise over the ambient), value / limit - 1 for a
lower one (life); a negative margin is a limit exceeded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .loads import resistance_at


@dataclass(frozen=True)
class Envelope:
    """Torque and speed limits of a motor (N*m, rad/s, V, ohm).

    Attributes
    ----------
    peak_torque : float
        inf when neither a peak torque nor a current limit is given.
    continuous_torque : float or None
    no_load_speed : float
        V / Ke (inf without a voltage limit).
    voltage_limit, hot_resistance, torque_constant, back_emf_constant : float
    """

    peak_torque: float
    continuous_torque: float | None
    no_load_speed: float
    voltage_limit: float
    hot_resistance: float
    torque_constant: float
    back_emf_constant: float

    @classmethod
    def of(cls, motor) -> "Envelope":
        """The envelope of a :class:`~servo_toolkit.components.motor.DCMotor`."""
        peak = motor.torque_constant * motor.current_limit
        if motor.peak_torque is not None:
            peak = min(peak, motor.peak_torque)
        hot = resistance_at(motor, motor.max_winding_temperature)
        cont = motor.continuous_torque
        if cont is None and motor.has_thermal_network:
            r_th = motor.thermal_resistance_winding + motor.thermal_resistance_housing
            cont = motor.torque_constant * math.sqrt((motor.max_winding_temperature - motor.ambient_temperature)
                                                     / (r_th * hot))
        if cont is not None:
            cont = min(cont, peak)
        return cls(peak, cont, motor.voltage_limit / motor.back_emf_constant, motor.voltage_limit, hot,
                   motor.torque_constant, motor.back_emf_constant)

    def voltage_torque(self, speed) -> np.ndarray:
        """Largest torque the supply drives at ``speed`` (rad/s), motoring (N*m, >= 0)."""
        w = np.abs(np.asarray(speed, dtype=float))
        return np.maximum(self.torque_constant * (self.voltage_limit - self.back_emf_constant * w)
                          / self.hot_resistance, 0.0)

    def braking_torque(self, speed) -> np.ndarray:
        """Largest torque the supply holds against ``speed`` (rad/s), braking (N*m, >= 0)."""
        w = np.abs(np.asarray(speed, dtype=float))
        return self.torque_constant * (self.voltage_limit + self.back_emf_constant * w) / self.hot_resistance

    def curve(self, top_speed: float, points: int = 200) -> tuple:
        """(speed, peak-limited motoring torque, peak-limited braking torque) of the envelope's
        edges from 0 to ``top_speed``."""
        w = np.linspace(0.0, top_speed, points)
        return (w, np.minimum(self.voltage_torque(w), self.peak_torque),
                np.minimum(self.braking_torque(w), self.peak_torque))

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        def fin(x):
            return None if x is None or not math.isfinite(x) else x
        return {"peak_torque_Nm": fin(self.peak_torque), "continuous_torque_Nm": fin(self.continuous_torque),
                "no_load_speed_rad_s": fin(self.no_load_speed), "voltage_limit_V": fin(self.voltage_limit),
                "hot_resistance_ohm": self.hot_resistance}


@dataclass(frozen=True)
class Margin:
    """One sized quantity against its limit.

    Attributes
    ----------
    name : str
    value, limit : float
    unit : str
    margin : float
        Fraction of the limit left (negative: exceeded).
    """

    name: str
    value: float
    limit: float
    unit: str
    margin: float

    @property
    def passed(self) -> bool:
        """True when the limit holds."""
        return self.margin >= 0

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        def fin(x):
            return x if math.isfinite(x) else None
        return {"name": self.name, "value": fin(self.value), "limit": fin(self.limit), "unit": self.unit,
                "margin": fin(self.margin), "passed": self.passed}


def upper(name: str, value: float, limit: float, unit: str, base: float = 0.0) -> Margin:
    """Margin of ``value`` under an upper ``limit``, measured from ``base`` (e.g. the
    ambient temperature)."""
    span = limit - base
    return Margin(name, value, limit, unit, (limit - value) / span if math.isfinite(value) else -math.inf)


def lower(name: str, value: float, limit: float, unit: str) -> Margin:
    """Margin of ``value`` over a lower ``limit``."""
    return Margin(name, value, limit, unit, value / limit - 1 if math.isfinite(value) else math.inf)


__all__ = ["Envelope", "Margin", "upper", "lower"]
