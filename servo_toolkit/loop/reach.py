"""A command within the actuator's reach: the speed, acceleration and jerk a motor can give
its load, from its voltage and current limits, the drivetrain's ratio and efficiency, the
friction and the inertia it drives (:mod:`.drive_budget`, the rule the default sine of
``check`` follows too).

At the output (rad or m), with the drivetrain's torque per ampere ``G = eta N Kt`` and the
driving-mode inertia ``J_d`` (the rotor's reflected, J_m N^2, included), each at its worst
from q0 over the move::

    a_max = (f I_max G - F) / J_d        F: the load's hinge moment and friction and the
                                         motor's friction through the drivetrain, eta N Fm
                                         (static or Coulomb, the larger); back-driven
                                         decelerations ask no more while eta_b <= 1 / eta
    v_max = (f V_max - R I_a) / (Ke N)   I_a = (J_d a_max + F) / G: the current at a_max,
                                         the back EMF the voltage share leaves
    j_max = a_max 2 pi f_bw              the acceleration rises within one period of the
                                         loop's bandwidth

with ``f`` (:data:`REACH_FRACTION`) the share of each limit the command may take: the rest
is the feedback's, to correct what the command leaves. A step passed through this
jerk-limited profile (:class:`~.profile.MoveProfile`) asks no current or voltage the motor
does not have, so the loop stays linear instead of saturating and winding up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

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
    #: the shares of the limits they come from (:class:`~.drive_budget.DriveBudget`)
    budget: object = field(default=None, repr=False)

    def allows(self, speed: float, acceleration: float) -> bool:
        """Whether a motion of peak ``speed`` and peak ``acceleration`` (a sine's A w and
        A w^2) keeps within the limits: the acceleration within ``a_max``, the speed within
        what the voltage leaves at that acceleration."""
        return self.budget.allows(speed, acceleration)

    def to_dict(self) -> dict:
        return {"v_max": self.v_max, "a_max": self.a_max, "j_max": self.j_max, "fraction": self.fraction}

    def describe(self, output_unit: str = "rad") -> str:
        u = "m" if output_unit == "m" else "rad"
        return (f"command within {self.fraction:.0%} of the motor's limits: speed {self.v_max:.4g} {u}/s, "
                f"acceleration {self.a_max:.4g} {u}/s^2, jerk {self.j_max:.4g} {u}/s^3")


def reach(scene, q0: float | None = None, bandwidth_hz: float | None = None,
          fraction: float = REACH_FRACTION, to: float | None = None) -> Reach:
    """The limits of :mod:`this module <servo_toolkit.loop.reach>` for ``scene`` at ``q0``
    (default mid-stroke), or over the stroke from ``q0`` to ``to``; ``bandwidth_hz`` sets
    the jerk (default the required bandwidth, the scene's or the default).

    Raises
    ------
    SceneError
        The motor cannot hold the load's friction and hinge moment within ``fraction`` of
        its current limit (key ``motor.current_limit``).
    """
    from ..errors import SceneError
    from .drive_budget import drive_budget
    q0 = scene.drivetrain.mid_stroke if q0 is None else float(q0)
    budget = drive_budget(scene, q0, q0 if to is None else float(to), fraction)
    motor = scene.motor
    a_max = budget.acceleration
    if not a_max > 0:
        raise SceneError("motor.current_limit", f"{fraction:.0%} of the {motor.current_limit:g} A limit gives "
                                                f"{budget.gain * budget.current:.4g} at the output, not more "
                                                f"than the load's friction and hinge moment and the motor's "
                                                f"friction {budget.held:.4g}: no move fits")
    v_max = budget.speed_at(a_max)
    if bandwidth_hz is None:
        from .requirements import requirements_of
        bandwidth_hz = next(r.value for r in requirements_of(scene) if r.name == "bandwidth")
    return Reach(v_max=v_max, a_max=a_max, j_max=a_max * 2 * math.pi * bandwidth_hz, fraction=fraction,
                 budget=budget)


def reach_profile(scene, distance: float, q0: float | None = None, bandwidth_hz: float | None = None,
                  fraction: float = REACH_FRACTION) -> MoveProfile:
    """A step of ``distance`` (rad, or m for an output travel) as the jerk-limited move the
    actuator can follow (:func:`reach`); simulate it with
    ``Reference.move(p.distance, p.v_max, p.a_max, p.j_max, at=...)``."""
    q0 = scene.drivetrain.mid_stroke if q0 is None else float(q0)
    r = reach(scene, q0, bandwidth_hz, fraction, to=q0 + distance)
    return MoveProfile(distance, r.v_max, r.a_max, r.j_max)


__all__ = ["REACH_FRACTION", "Reach", "reach", "reach_profile"]
