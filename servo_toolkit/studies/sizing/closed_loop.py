"""The motor's torque and speed along a duty cycle from the nonlinear closed-loop simulation.

The simulation's position commands are holds, sines, steps and ramps
(:class:`~servo_toolkit.sim.Reference`), so the cycle runs segment by segment: each
``dwell`` (a hold), ``sine`` and ``step`` segment is its own simulation of the scene's
designed loop from rest at the segment's start position, with the segment's load as the
hinge moment, over the segment's duration; the motor torque is Kt times the current the
loop draws (its limits included) and the speed the motor's. A hold at a stroke end may
touch it: the runs use the elastic end stop (``stroke_end="stop"``). A ``step`` is commanded as a
true step (the loop shapes the move, not the sizing's triangular profile). ``ramp`` and
``points`` segments keep their inverse-dynamics torque and speed: a trapezoid and a spline
are no command of the simulation.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

#: segment kinds the closed loop runs
RUN_KINDS = ("dwell", "sine", "step")


def _reference(seg, q0: float):
    from ...sim import Reference
    if seg.kind == "sine":
        return Reference.sine(seg.amplitude, seg.frequency, offset=q0)
    if seg.kind == "step":
        return Reference.step(seg.to - q0, 0.0, offset=q0)
    return Reference.step(0.0, 0.0, offset=q0)


def closed_loop_loads(scene, motion, loads, *, progress: bool = False):
    """(motor torque, motor speed) at the samples of ``motion`` (a
    :class:`~.cycle.CycleMotion`), from the closed-loop simulation where a segment allows
    (module docstring) and from ``loads`` (the inverse dynamics) elsewhere.

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
    torque, speed = loads.motor_torque.copy(), loads.motor_speed.copy()
    controller, _ = controller_for(scene)
    kt = scene.motor.torque_constant
    q0 = scene.drivetrain.mid_stroke if duty.start is None else duty.start
    t_start = 0.0
    for i, seg in progress_bar(list(enumerate(duty.segments)), show=progress, desc="closed-loop segments"):
        if seg.kind in RUN_KINDS:
            idx = np.flatnonzero(motion.segment == i)
            load = scene.load.hinge_moment if seg.load is None else seg.load
            run_scene = replace(scene, load=replace(scene.load, hinge_moment=load))
            res = simulate(run_scene, controller, reference=_reference(seg, q0), duration=seg.duration,
                           method="auto", options=ModelOptions(stroke_end="stop"))
            local = motion.t[idx] - t_start
            torque[idx] = kt * np.interp(local, res.times, res.motor_current)
            speed[idx] = np.interp(local, res.times, res.motor_speed)
        t_start += seg.duration
        q0 = segment_end(seg, q0)
    return torque, speed


__all__ = ["closed_loop_loads", "RUN_KINDS"]
