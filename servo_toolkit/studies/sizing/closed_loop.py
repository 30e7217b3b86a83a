"""The motor's torque, speed, current and voltage along a duty cycle from the nonlinear
closed-loop simulation.

The simulation's position commands are holds, sines, steps and constant-speed ramps
(:class:`~servo_toolkit.sim.Reference`), so the cycle runs segment by segment: each ``dwell``
(a hold) and ``sine`` segment is its own simulation of the scene's designed loop from rest at
the segment's start position, with the segment's load as the hinge moment, over the
segment's duration. A hold at a stroke end may touch it: the runs use the elastic end stop
(``stroke_end="stop"``).

``ramp``, ``step`` and ``points`` segments keep their inverse-dynamics torque and speed: a
trapezoid, a step's move over its ``rise_time`` and a spline are no position command of the
simulation (a true step would ask the loop for a move the sizing does not prescribe), so
these segments are sized on the prescribed motion in both modes; :attr:`ClosedLoopLoads.notes`
says which.

The winding is hot in the simulation: its resistance is R(T_max) at the motor's
``max_winding_temperature``, as in every voltage figure of the inverse dynamics and the
envelope, so the supply's headroom is judged on the same winding in both modes (the loop is
the scene's design, made on the cold winding). The voltage of a simulated sample is the
simulation's own: the current loop's command, clamped at the supply's ``voltage_limit``; it
never exceeds the supply, and the time it spends at the clamp is reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

#: segment kinds the closed loop runs
RUN_KINDS = ("dwell", "sine")
#: a voltage within this fraction of the supply's limit is at the clamp
CLAMP_TOLERANCE = 1e-6


@dataclass(frozen=True)
class ClosedLoopLoads:
    """What the closed loop draws along one cycle (arrays over the cycle's samples).

    Attributes
    ----------
    torque, speed, current : numpy.ndarray
        Motor torque Kt i (N*m), speed (rad/s) and current (A).
    voltage : numpy.ndarray
        The simulation's voltage (V) on the simulated samples, nan elsewhere.
    simulated : numpy.ndarray of bool
        Samples taken from a simulation (the others keep the inverse dynamics).
    peak_current, peak_voltage : float
        Largest |i| and |u| over every simulation's own records (A, V; 0 without a
        simulated segment).
    clamp_time : float
        Time per cycle the voltage sat at the supply's limit (s).
    tracking_error : float
        Largest |output - command| of the simulations (rad or m).
    hot_resistance : float
        The winding resistance the simulations ran with (ohm).
    notes : tuple of str
    """

    torque: np.ndarray
    speed: np.ndarray
    current: np.ndarray
    voltage: np.ndarray
    simulated: np.ndarray
    peak_current: float
    peak_voltage: float
    clamp_time: float
    tracking_error: float
    hot_resistance: float
    notes: tuple


def _reference(seg, q0: float):
    from ...sim import Reference
    if seg.kind == "sine":
        return Reference.sine(seg.amplitude, seg.frequency, offset=q0)
    return Reference.step(0.0, 0.0, offset=q0)


def hot_scene(scene):
    """The scene with its motor's winding at ``max_winding_temperature``."""
    from .loads import resistance_at
    motor = scene.motor
    hot = resistance_at(motor, motor.max_winding_temperature)
    return replace(scene, motor=replace(motor, resistance=hot, resistance_temperature=motor.max_winding_temperature))


def closed_loop_loads(scene, motion, loads, *, progress: bool = False, controller=None) -> ClosedLoopLoads:
    """The :class:`ClosedLoopLoads` at the samples of ``motion`` (a
    :class:`~.cycle.CycleMotion`): from the closed-loop simulation where a segment allows
    (module docstring), from ``loads`` (the inverse dynamics) elsewhere; ``controller``
    (default the scene's design) runs the loop.

    Raises
    ------
    SimulationError
        A run leaves its validity domain.
    """
    from ...core.progress import progress_bar
    from ...scene.duty_cycle import segment_end
    from ...sim import ModelOptions, simulate
    from ...sim.simulate import controller_for
    duty = scene.duty_cycle
    kt = scene.motor.torque_constant
    torque, speed = loads.motor_torque.copy(), loads.motor_speed.copy()
    current = torque / kt
    voltage = np.full(torque.size, np.nan)
    simulated = np.zeros(torque.size, bool)
    if controller is None and any(seg.kind in RUN_KINDS for seg in duty.segments):
        controller, _ = controller_for(scene)
    hot = hot_scene(scene)
    v_lim = scene.motor.voltage_limit
    q0 = scene.drivetrain.mid_stroke if duty.start is None else duty.start
    t_start, peak_i, peak_u, clamp, error = 0.0, 0.0, 0.0, 0.0, 0.0
    kept = []
    for i, seg in progress_bar(list(enumerate(duty.segments)), show=progress, desc="closed-loop segments"):
        if seg.kind in RUN_KINDS:
            idx = np.flatnonzero(motion.segment == i)
            load = scene.load.hinge_moment if seg.load is None else seg.load
            run_scene = replace(hot, load=replace(hot.load, hinge_moment=load))
            res = simulate(run_scene, controller, reference=_reference(seg, q0), duration=seg.duration,
                           method="auto", options=ModelOptions(stroke_end="stop"))
            local = motion.t[idx] - t_start
            current[idx] = np.interp(local, res.times, res.motor_current)
            torque[idx] = kt * current[idx]
            speed[idx] = np.interp(local, res.times, res.motor_speed)
            voltage[idx] = np.interp(local, res.times, res.motor_voltage)
            simulated[idx] = True
            peak_i = max(peak_i, float(np.abs(res.motor_current).max()))
            peak_u = max(peak_u, float(np.abs(res.motor_voltage).max()))
            error = max(error, float(np.abs(res.output_angle - res.reference_angle).max()))
            if math.isfinite(v_lim):
                at = np.abs(res.motor_voltage) >= v_lim * (1 - CLAMP_TOLERANCE)
                clamp += seg.duration * float(at.mean())
        else:
            kept.append(f"{i} ({seg.kind})")
        t_start += seg.duration
        q0 = segment_end(seg, q0)
    notes = [f"simulated with the winding hot ({hot.motor.resistance:.4g} ohm at "
             f"{scene.motor.max_winding_temperature - 273.15:.4g} degC); the voltage of a simulated segment is "
             "the current loop's own, clamped at the supply"]
    if simulated.any():
        from ...core.output_units import OutputUnit
        unit = OutputUnit(scene.drivetrain.output_unit)
        notes.append(f"largest tracking error of the simulated segments {float(unit.show(error)):.3g} {unit.shown}")
    if kept:
        notes.append("segments " + ", ".join(kept) + " keep the inverse dynamics: their move (a trapezoid, a step's "
                     "rise, a spline) is no position command of the simulation")
    if clamp > 0:
        notes.append(f"the voltage sits at the supply's {v_lim:.4g} V for {clamp:.4g} s of the cycle "
                     f"({clamp / motion.duration:.1%}): the loop asks more than the supply gives there")
    return ClosedLoopLoads(torque, speed, current, voltage, simulated, peak_i, peak_u, clamp, error,
                           hot.motor.resistance, tuple(notes))


__all__ = ["ClosedLoopLoads", "closed_loop_loads", "hot_scene", "RUN_KINDS"]
