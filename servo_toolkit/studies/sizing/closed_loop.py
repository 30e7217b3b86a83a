"""The motor's torque, speed, current and voltage along a duty cycle from the nonlinear
closed-loop simulation.

Every segment runs as its own simulation of the scene's designed loop from rest at the
segment's start position, with the segment's load as the hinge moment, over the segment's
duration, with friction that holds (``ModelOptions(friction="stick")``: a dwell rests, a sine
reverses, a hold may sit below breakaway): a ``dwell`` is a hold and a ``sine`` a sine command; a ``ramp`` (trapezoid), a
``step`` (its move over ``rise_time``, then the hold) and a ``points`` spline are sampled
commands (:meth:`~servo_toolkit.sim.Reference.table`: a cubic spline through the prescribed
motion at :func:`table_spacing`, evaluated in the compiled loop with its exact derivatives,
so a model-based feedforward follows it). A hold at a stroke end may touch it: the runs use
the elastic end stop (``stroke_end="stop"``).

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

#: largest spacing of a sampled command (s), and the fewest samples over its segment and over
#: the shortest phase of its motion (a ramp's acceleration, a step's rise)
TABLE_SPACING, TABLE_MIN_SAMPLES, PHASE_MIN_SAMPLES = 1e-3, 200, 40
#: most samples of one segment's command
TABLE_MAX_SAMPLES = 200_000
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


def table_spacing(seg) -> float:
    """Sample spacing (s) of a segment's sampled command: at most :data:`TABLE_SPACING`, with
    at least :data:`TABLE_MIN_SAMPLES` over the segment and :data:`PHASE_MIN_SAMPLES` over
    its shortest phase (a ramp's ``accel_time``, half a step's ``rise_time``), and four
    samples in a points file's smallest interval."""
    h = min(TABLE_SPACING, seg.duration / TABLE_MIN_SAMPLES)
    if seg.kind == "ramp":
        h = min(h, seg.accel_time / PHASE_MIN_SAMPLES)
    elif seg.kind == "step":
        h = min(h, 0.5 * seg.rise_time / PHASE_MIN_SAMPLES)
    elif seg.kind == "points" and len(seg.times) > 1:
        h = min(h, float(np.min(np.diff(seg.times))) / 4)
    return max(h, seg.duration / TABLE_MAX_SAMPLES)


def _reference(seg, q0: float):
    from ...sim import Reference
    from .cycle import segment_motion
    if seg.kind == "sine":
        return Reference.sine(seg.amplitude, seg.frequency, offset=q0)
    if seg.kind == "dwell":
        return Reference.step(0.0, 0.0, offset=q0)
    n = int(math.ceil(seg.duration / table_spacing(seg) - 1e-9))
    t = np.linspace(0.0, seg.duration, n + 1)
    return Reference.table(t, segment_motion(seg, q0, t)[0], offset=0.0)


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
    from ...sim import ModelOptions, build_model, run
    from ...sim.simulate import controller_for
    duty = scene.duty_cycle
    kt = scene.motor.torque_constant
    torque, speed = loads.motor_torque.copy(), loads.motor_speed.copy()
    current = torque / kt
    voltage = np.full(torque.size, np.nan)
    simulated = np.zeros(torque.size, bool)
    if controller is None:
        controller, _ = controller_for(scene)
    hot = hot_scene(scene)
    v_lim = scene.motor.voltage_limit
    q0 = scene.drivetrain.mid_stroke if duty.start is None else duty.start
    t_start, peak_i, peak_u, clamp, error = 0.0, 0.0, 0.0, 0.0, 0.0
    for i, seg in progress_bar(list(enumerate(duty.segments)), show=progress, desc="closed-loop segments"):
        idx = np.flatnonzero(motion.segment == i)
        load = scene.load.hinge_moment if seg.load is None else seg.load
        run_scene = replace(hot, load=replace(hot.load, hinge_moment=load))
        # a sine segment may hold part of a period: run the model itself, not simulate's whole-period rule
        model = build_model(run_scene, controller, ModelOptions(stroke_end="stop", friction="stick"))
        res = run(model, _reference(seg, q0), seg.duration, "auto")
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
        t_start += seg.duration
        q0 = segment_end(seg, q0)
    notes = [f"simulated with the winding hot ({hot.motor.resistance:.4g} ohm at "
             f"{scene.motor.max_winding_temperature - 273.15:.4g} degC); the voltage of a simulated segment is "
             "the current loop's own, clamped at the supply", "friction that holds at every node that gives it "
             "(the motor's, each stage's, the load's): a duty cycle rests, holds and reverses"]
    if simulated.any():
        from ...core.output_units import OutputUnit
        unit = OutputUnit(scene.drivetrain.output_unit)
        notes.append(f"largest tracking error of the simulated segments {float(unit.show(error)):.3g} {unit.shown}")
    tabled = [f"{i} ({seg.kind})" for i, seg in enumerate(duty.segments) if seg.kind in ("ramp", "step", "points")]
    if tabled:
        notes.append("segments " + ", ".join(tabled) + " run their prescribed motion as a sampled command (a cubic "
                     "spline through it, the compiled loop's table command)")
    if clamp > 0:
        notes.append(f"the voltage sits at the supply's {v_lim:.4g} V for {clamp:.4g} s of the cycle "
                     f"({clamp / motion.duration:.1%}): the loop asks more than the supply gives there")
    return ClosedLoopLoads(torque, speed, current, voltage, simulated, peak_i, peak_u, clamp, error,
                           hot.motor.resistance, tuple(notes))


__all__ = ["ClosedLoopLoads", "closed_loop_loads", "hot_scene", "table_spacing"]
