"""What ``check`` requires of the nonlinear closed loop in time, and where each figure's
requirement comes from: the scene's ``[requirements]`` time keys
(:mod:`servo_toolkit.scene.time_requirements`) or the defaults below, stated as defaults.

The commands:

- the step: ``step_amplitude``, default half the output's default command (1 deg, 0.5 mm);
- the requirement sine at the required bandwidth (as the large-signal rows): ``sine_amplitude``,
  else the scene's sweep study's amplitude, else the output's default (2 deg, 1 mm) reduced to
  what the actuator can follow as a rigid body at that frequency with half its current and
  half its voltage (:func:`followable_amplitude`, the command's reach with that share: the
  drivetrain's efficiency and driving-mode inertia counted; the other half is the loop's, for
  its corrections, the friction and the load's moment).

The rows (ID, key, default):

============================  ============================  =================================================
``step_overshoot``            ``max_overshoot``             20 % of the step
``step_settling_time``        ``max_settling_time``         4 periods of the required bandwidth
``position_error_at_rest``    ``max_position_error_at_rest``  2 % of the step
``limit_cycle``               ``max_limit_cycle``           2 % of the step (amplitude, after the step)
``tracking_error``            ``max_tracking_error``        1.25 x the linear loop's peak error on the sine
``current_ripple``            ``max_current_ripple``        10 % of the continuous current, else 5 % of the limit
``rms_current``               ``max_rms_current``           the continuous current (a row only when the motor
                                                            gives ``continuous_torque`` or the key is set)
``time_at_current_limit``     ``max_time_at_current_limit``  0 ms in the sine (within 1 % of the limit)
``time_at_voltage_limit``     ``max_time_at_voltage_limit``  0 ms in the sine (within 1 % of the limit)
============================  ============================  =================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...core.output_units import output_unit
from ...loop.drive_budget import followable_sine
from ..sweep.kind import SWEEP
# the default current ripple, of the continuous current else of the current limit: the
# allowance the loop design keeps the encoder's and the play's ripple within
from ...loop.actuator_bounds import RIPPLE_OF_CONTINUOUS, RIPPLE_OF_LIMIT  # noqa: F401 - re-exported

DEFAULT_OVERSHOOT = 0.20
#: the default settling time, in periods of the required bandwidth
SETTLING_PERIODS = 4.0
#: the default position error at rest and limit cycle amplitude, as a fraction of the step
REST_FRACTION = 0.02
#: the default tracking error, relative to the linear closed loop's on the same sine
TRACKING_FACTOR = 1.25
#: the share of the current and the voltage a default sine may take to follow as a rigid body
FOLLOW_SHARE = 0.5
#: row ID -> the ``[requirements]`` key that sets its bound, in the rows' order
ROW_KEYS = {"step_overshoot": "max_overshoot", "step_settling_time": "max_settling_time",
            "position_error_at_rest": "max_position_error_at_rest", "limit_cycle": "max_limit_cycle",
            "tracking_error": "max_tracking_error", "current_ripple": "max_current_ripple",
            "rms_current": "max_rms_current", "time_at_current_limit": "max_time_at_current_limit",
            "time_at_voltage_limit": "max_time_at_voltage_limit"}


@dataclass(frozen=True)
class Bound:
    """One time requirement, resolved.

    Attributes
    ----------
    name : str
        The row's ID.
    value : float
        SI (fraction, s, rad or m, A).
    unit : str
        Shown unit; ``factor`` takes SI to it.
    factor : float
    source : str
        ``"scene"`` or ``"default"``.
    rule : str
        The default's rule in words ("" for a scene's value).
    """

    name: str
    value: float
    unit: str
    factor: float
    source: str
    rule: str = ""


@dataclass(frozen=True)
class Plan:
    """The commands and the bounds of the nonlinear rows.

    Attributes
    ----------
    step, sine_amplitude : float
        SI (rad or m).
    frequency : float
        The sine's frequency (Hz): the required bandwidth.
    bounds : tuple of Bound
    notes : tuple of str
        Where each command and default comes from.
    linear_tracking_error : float
        The linear closed loop's peak |command - output| on the sine (SI).
    """

    step: float
    sine_amplitude: float
    frequency: float
    bounds: tuple
    notes: tuple
    linear_tracking_error: float

    def bound(self, name: str) -> Bound | None:
        """The bound of a row, or None."""
        return next((b for b in self.bounds if b.name == name), None)

    @property
    def settling_time(self) -> float:
        """The settling allowance (s)."""
        return self.bound("step_settling_time").value

    @property
    def rest_band(self) -> float:
        """Half-width of the settling band (SI): 2 % of the step, or the error allowed at rest
        when larger."""
        return max(REST_FRACTION * abs(self.step), self.bound("position_error_at_rest").value)


def followable_amplitude(scene, q0: float, frequency: float) -> float:
    """The largest output amplitude (SI) a sine about ``q0`` at ``frequency`` (Hz) can have
    for the motor to follow it as a rigid body with :data:`FOLLOW_SHARE` of its current
    limit and of its voltage: the command's reach (:func:`servo_toolkit.loop.reach.reach`)
    with that share, over the stroke the sine sweeps, the hinge moment and the friction left
    to the other share (the loop's). Its peak acceleration A w^2 asks the current
    ``J_d A w^2 / (eta N Kt)`` (J_d the driving-mode inertia, eta the efficiency) and its
    voltage ``R i + Ke N A w`` (the two parts' peaks added)
    (:mod:`servo_toolkit.loop.drive_budget`). Infinite without limits."""
    return followable_sine(scene, q0, frequency, FOLLOW_SHARE)


def continuous_current(motor) -> float | None:
    """The motor's continuous current (A): its continuous torque over Kt, None without one."""
    ct = getattr(motor, "continuous_torque", None)
    return None if ct is None else ct / motor.torque_constant


def plan(scene, design) -> Plan:
    """The commands and bounds of ``design`` (a DesignResult of ``scene``).

    Raises
    ------
    SceneError
        A position requirement given in the other dimension than the output's.
    """
    from ..sweep.points import study_points
    u = output_unit(scene)
    given = scene.requirements.time
    given.check_output(u.linear)
    f = next(c.required for c in design.requirements if c.name == "bandwidth")
    notes = []
    step = given.step_amplitude
    if step is None:
        step = 0.5 * u.default_amplitude
        notes.append(f"step {u.text(step, 3)}: default (half the output's default command)")
    amp = given.sine_amplitude
    if amp is None and scene.studies_of_kind(SWEEP.name):
        amp = float(study_points(scene)[2][0])
        notes.append(f"sine {u.text(amp, 3)} at {f:g} Hz: the amplitude of the scene's sweep study")
    elif amp is None:
        reach = followable_amplitude(scene, design.q0, f)
        amp = min(u.default_amplitude, reach)
        why = "" if amp == u.default_amplitude else (
            f", reduced from {u.text(u.default_amplitude, 3)} to what the actuator follows as a rigid body at "
            f"{f:g} Hz with half its current and voltage")
        notes.append(f"sine {u.text(amp, 3)} at {f:g} Hz: default{why}")
    lin = complex(design.block("closed_loop")(2j * np.pi * f))
    lin_err = abs(1.0 - lin) * amp
    motor = scene.motor
    i_cont = continuous_current(motor)
    pos = (u.shown, u.factor)
    table = [
        ("step_overshoot", DEFAULT_OVERSHOOT, ("%", 100.0), f"{100 * DEFAULT_OVERSHOOT:g} % of the step"),
        ("step_settling_time", SETTLING_PERIODS / f, ("ms", 1e3),
         f"{SETTLING_PERIODS:g} periods of the required bandwidth {f:g} Hz"),
        ("position_error_at_rest", REST_FRACTION * abs(step), pos, f"{100 * REST_FRACTION:g} % of the step"),
        ("limit_cycle", REST_FRACTION * abs(step), pos, f"{100 * REST_FRACTION:g} % of the step"),
        ("tracking_error", TRACKING_FACTOR * lin_err, pos,
         f"{TRACKING_FACTOR:g} x the linear closed loop's {u.text(lin_err, 3)} on the same sine"),
        ("current_ripple",
         RIPPLE_OF_CONTINUOUS * i_cont if i_cont is not None else RIPPLE_OF_LIMIT * motor.current_limit, ("A", 1.0),
         f"{100 * RIPPLE_OF_CONTINUOUS:g} % of the continuous current" if i_cont is not None
         else f"{100 * RIPPLE_OF_LIMIT:g} % of the current limit"),
        ("rms_current", i_cont, ("A", 1.0), "the motor's continuous current"),
        ("time_at_current_limit", 0.0 if math.isfinite(motor.current_limit) else None,
         ("ms", 1e3), "none in the sine"),
        ("time_at_voltage_limit", 0.0 if math.isfinite(motor.voltage_limit) else None,
         ("ms", 1e3), "none in the sine"),
    ]
    bounds = []
    for name, default, (unit, factor), rule in table:
        value = getattr(given, ROW_KEYS[name])
        if value is not None:
            bounds.append(Bound(name, float(value), unit, factor, "scene"))
        elif default is not None and math.isfinite(default):
            bounds.append(Bound(name, float(default), unit, factor, "default", rule))
    return Plan(float(step), float(amp), float(f), tuple(bounds), tuple(notes), float(lin_err))


__all__ = ["Bound", "DEFAULT_OVERSHOOT", "FOLLOW_SHARE", "Plan", "REST_FRACTION", "ROW_KEYS", "SETTLING_PERIODS",
           "TRACKING_FACTOR", "continuous_current", "followable_amplitude", "plan"]
