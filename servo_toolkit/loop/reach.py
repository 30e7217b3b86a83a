"""A command within the actuator's reach: the speed, acceleration and jerk a motor can give
its load, from its voltage and current limits and the inertia it drives.

At the output (rad or m), with the drivetrain's torque per ampere ``G = eta N Kt`` and the
whole inertia ``J = J1 + J2`` it moves (the rotor's reflected, J_m N^2, included)::

    a_max = f (G I_max - F) / J          F: the load's hinge moment and friction (static or
                                         Coulomb, the larger; the stages' is in eta)
    v_max = f (V_max - R I_a) / (Ke N)   I_a = J a_max / G: the back EMF the voltage leaves
    j_max = a_max 2 pi f_bw              the acceleration rises within one period of the
                                         loop's bandwidth

with ``f`` (:data:`REACH_FRACTION`) the share of each limit the command may take: the rest
is the feedback's, to correct what the command leaves. A step passed through this
jerk-limited profile (:class:`~.profile.MoveProfile`) asks no current or voltage the motor
does not have, so the loop stays linear instead of saturating and winding up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .profile import MoveProfile

#: share of the current and voltage limits a command may take (the rest is the feedback's)
REACH_FRACTION = 0.8


@dataclass(frozen=True)
class Reach:
    """Speed, acceleration and jerk limits at the output (rad/s, rad/s^2, rad/s^3; m/s...)."""

    v_max: float
    a_max: float
    j_max: float
    fraction: float = REACH_FRACTION

    def to_dict(self) -> dict:
        return {"v_max": self.v_max, "a_max": self.a_max, "j_max": self.j_max, "fraction": self.fraction}

    def describe(self, output_unit: str = "rad") -> str:
        u = "m" if output_unit == "m" else "rad"
        return (f"command within {self.fraction:.0%} of the motor's limits: speed {self.v_max:.4g} {u}/s, "
                f"acceleration {self.a_max:.4g} {u}/s^2, jerk {self.j_max:.4g} {u}/s^3")


def reach(scene, q0: float | None = None, bandwidth_hz: float | None = None,
          fraction: float = REACH_FRACTION) -> Reach:
    """The limits of :mod:`this module <servo_toolkit.loop.reach>` for ``scene`` at ``q0``
    (default mid-stroke); ``bandwidth_hz`` sets the jerk (default the required bandwidth,
    the scene's or the default).

    Raises
    ------
    SceneError
        The motor cannot hold the load's friction and hinge moment within ``fraction`` of
        its current limit (key ``motor.current_limit``).
    """
    from ..errors import SceneError
    from ..plant.linear import plant_parameters
    p = plant_parameters(scene, q0)
    motor = scene.motor
    gain = p.torque_gain
    load = scene.load
    held = abs(load.hinge_moment) + max(abs(load.coulomb_friction), abs(load.static_friction or 0.0))
    spare = fraction * gain * motor.current_limit - held
    if not spare > 0:
        raise SceneError("motor.current_limit", f"{fraction:.0%} of the {motor.current_limit:g} A limit gives "
                                                f"{fraction * gain * motor.current_limit:.4g} at the output, not more "
                                                f"than the load's friction and hinge moment {held:.4g}: no move fits")
    inertia = p.J1 + p.J2
    a_max = spare / inertia
    i_acc = inertia * a_max / gain
    v_max = fraction * max(motor.voltage_limit - motor.resistance * i_acc, 0.0) / (motor.back_emf_constant * p.N)
    if bandwidth_hz is None:
        from .requirements import requirements_of
        bandwidth_hz = next(r.value for r in requirements_of(scene) if r.name == "bandwidth")
    return Reach(v_max=v_max, a_max=a_max, j_max=a_max * 2 * math.pi * bandwidth_hz, fraction=fraction)


def reach_profile(scene, distance: float, q0: float | None = None, bandwidth_hz: float | None = None,
                  fraction: float = REACH_FRACTION) -> MoveProfile:
    """A step of ``distance`` (rad, or m for an output travel) as the jerk-limited move the
    actuator can follow (:func:`reach`); simulate it with
    ``Reference.move(p.distance, p.v_max, p.a_max, p.j_max, at=...)``."""
    r = reach(scene, q0, bandwidth_hz, fraction)
    return MoveProfile(distance, r.v_max, r.a_max, r.j_max)


__all__ = ["REACH_FRACTION", "Reach", "reach", "reach_profile"]
