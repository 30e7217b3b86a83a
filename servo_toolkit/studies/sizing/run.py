"""``size(scene)``: the motor and the screw along the scene's duty cycle, against their limits."""

from __future__ import annotations

import math

import numpy as np

from ...errors import SceneError
from ...scene.argument import as_scene
from .cycle import sample_cycle
from .envelope import Envelope, lower, upper
from .life import screw_lives
from ..mechanisms.inverse_dynamics import friction_notes
from .loads import cycle_loads, electrical, screw_index
from .result import SizingResult
from .sweep import ratio_sweep
from .thermal import ThermalNetwork, cycle_temperatures

#: 0 degC in K
KELVIN = 273.15
#: how the motor's loads are found
METHODS = ("inverse_dynamics", "closed_loop")


def size(scene, *, closed_loop: bool = False, losses: str = "directional", sweep: bool = True,
         progress: bool = False, controller=None) -> SizingResult:
    """Size the motor and the screw of a scene along its ``[duty_cycle]``.

    Parameters
    ----------
    scene : Scene or path-like
        A scene with a ``[duty_cycle]`` (a path is loaded with :func:`~servo_toolkit.scene.load_scene`).
    closed_loop : bool
        Take the motor's torque, speed, current and voltage from the nonlinear closed-loop
        simulation of every segment of the cycle (:mod:`servo_toolkit.studies.sizing.closed_loop`:
        the winding hot, the simulation's own voltage, ramps, steps and points as sampled
        commands) instead of the inverse dynamics; the screw's thrust and its lives stay with
        the inverse dynamics.
    losses : {"directional", "none"}
        Stage-loss model of the inverse dynamics.
    sweep : bool
        Also sweep the first stage's ratio (:mod:`servo_toolkit.studies.sizing.sweep`).
    progress : bool
        Progress bar of the closed-loop runs.
    controller : CascadeController, optional
        The loop the closed-loop simulation runs; default the scene's design
        (:func:`servo_toolkit.loop.design`).

    Returns
    -------
    SizingResult

    Raises
    ------
    SceneError
        The scene has no duty cycle or no motor-driven drivetrain.
    SimulationError
        The inverse dynamics or the simulation leaves its validity domain.

    Examples
    --------
    >>> import servo_toolkit as st
    >>> result = st.size("scenes/ema_reference.toml")    # doctest: +SKIP
    >>> result.margins[0].name                            # doctest: +SKIP
    'peak torque'
    """
    scene = as_scene(scene)
    duty = scene.duty_cycle
    if duty is None:
        raise SceneError("duty_cycle", "missing table: size needs a [duty_cycle] with [[duty_cycle.segments]]")
    drivetrain = scene.drivetrain
    motor = drivetrain.motor
    motion = sample_cycle(duty, drivetrain.mid_stroke, scene.load.hinge_moment)
    loads = cycle_loads(drivetrain, motion, losses, scene.stage_friction)
    hot = motor.max_winding_temperature
    torque, speed = loads.motor_torque, loads.motor_speed
    elec = electrical(motor, torque, speed, hot)
    current, voltage = elec["current"], elec["voltage"]
    peak_i, peak_u, clamp = float(np.abs(current).max()), float(np.abs(voltage).max()), None
    notes = friction_notes(scene)
    method = "inverse_dynamics"
    if closed_loop:
        from .closed_loop import closed_loop_loads
        cl = closed_loop_loads(scene, motion, loads, progress=progress, controller=controller)
        method, torque, speed, current = "closed_loop", cl.torque, cl.speed, cl.current
        steady = electrical(motor, torque, speed, hot)["voltage"]
        voltage = np.where(cl.simulated, cl.voltage, steady)
        # the peaks over the simulations' own records, which the cycle's samples may step over
        peak_i = max(float(np.abs(current).max()), cl.peak_current)
        peak_u = max(float(np.abs(voltage).max()), cl.peak_voltage)
        notes += list(cl.notes)
        clamp = cl.clamp_time
    env = Envelope.of(motor)
    net = ThermalNetwork.from_motor(motor)
    thermal = cycle_temperatures(net, current, motion.weight) if net else None
    lives, stage = [], None
    if loads.screw_thrust is not None:   # the prescribed motion's thrust, in both modes
        stage = drivetrain.stages[screw_index(drivetrain)]
        lives = screw_lives(stage, loads.screw_thrust, loads.screw_speed, motion.weight, motion.duration)
        if closed_loop:
            notes.append("the screw's thrust, its lives and static load are the inverse dynamics' of the prescribed "
                         "motion (the thrust is no output of the simulation)")
    rms_t = motion.rms(torque)
    margins = []   # a limit the scene does not give (no peak torque nor current limit) is no margin
    if math.isfinite(env.peak_torque):
        margins.append(upper("peak torque", max(float(np.abs(torque).max()), motor.torque_constant * peak_i),
                             env.peak_torque, "N*m"))
    if env.continuous_torque is not None:
        margins.append(upper("RMS torque", rms_t, env.continuous_torque, "N*m"))
    if math.isfinite(motor.current_limit):
        margins.append(upper("peak current", peak_i, motor.current_limit, "A"))
    if math.isfinite(motor.voltage_limit):
        margins.append(upper("peak voltage", peak_u, motor.voltage_limit, "V"))
    if thermal is not None:
        margins.append(upper("winding temperature", thermal.peak_winding - KELVIN, hot - KELVIN, "degC",
                             motor.ambient_temperature - KELVIN))
    static = getattr(stage, "static_load_rating", None)
    statics = [] if static is None else [   # a roller screw's static rating against the peak thrust on its last nut
        upper(f"static load {stage.name}", float(np.abs(loads.screw_thrust).max()), static, "N")]
    life_margins = [] if duty.required_life is None else [
        lower(f"L10 {life.part}", life.hours, duty.required_life / 3600, "h") for life in lives]
    margins += statics + life_margins
    lead_swept = screw_index(drivetrain) == 0
    # the margins no factor on the first stage's ratio changes: the static load, and the lives
    # behind a gear (which leaves the screw's speed as it is)
    fixed = statics + ([] if lead_swept else life_margins)
    if not margins:
        notes.append("no limit to size against: the scene gives the motor no current or voltage limit, peak or "
                     "continuous torque nor thermal network, and the duty cycle no required life")
    sweep_result = None
    if sweep:
        factors = np.geomspace(duty.ratio_range[0], duty.ratio_range[1], duty.ratio_points)
        sweep_result = ratio_sweep(drivetrain, motion, loads, (("scene motor", motor),) + tuple(duty.motors),
                                   factors, required_bandwidth=scene.requirements.bandwidth,
                                   lives=lives if lead_swept else None,
                                   required_life=duty.required_life, display=scene.display,
                                   fixed_limits_hold=all(m.passed for m in fixed))
    power = voltage * current
    mechanical = torque * speed
    # the energy returned with the winding cold (at the ambient): the hot winding's larger loss
    # would return less, the wrong side for the braking resistor or bus capacitance it sizes
    cold = electrical(motor, torque, speed, motor.ambient_temperature)["electrical_power"]
    regen = float(np.sum(np.maximum(-cold, 0.0) * motion.weight))
    return SizingResult(
        scene=scene.name, output_unit=drivetrain.output_unit, method=method, motion=motion,
        motor_torque=torque, motor_speed=speed, current=current, voltage=voltage,
        electrical_power=power, mechanical_power=mechanical,
        envelope=env, rms_torque=rms_t, rms_current=motion.rms(current),
        peak_power=float(np.abs(mechanical).max()),
        peak_electrical_power=float(power.max()), regenerated_energy=regen,
        thermal=thermal, lives=tuple(lives), margins=tuple(margins), sweep=sweep_result,
        screw_thrust=loads.screw_thrust, notes=tuple(notes), voltage_clamp_time=clamp)


__all__ = ["size", "METHODS"]
