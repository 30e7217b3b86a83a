"""``excite(scene, ...)``: an excitation for a rig's drive, as large as the scene's limits
allow, and the model's run of it.

The steps: the loop's design gives the default band (crossover and first mode); the plan
gives the period and the lines (:mod:`.plan`); the signal is synthesized
(:mod:`.signals`); the linear loop of the drive taking it (:mod:`.drive`) predicts the
current, voltage and motion per unit of its peak, which sets the amplitude within the
limits and says whether it clears the breakaway and backlash levels (:mod:`.levels`); the
compiled model runs the whole excitation from rest at the operating point, sample by sample
as the drive takes it, and its peaks are checked against the limits (a chosen amplitude is
lowered where the run passes 90 % of one, which the linear loop's prediction may miss: the
current loop's answer to the held samples' steps, the losses; a given one is refused). The run's records
are the predicted log, and its H1 estimate at the lines (the rectangular window on each
averaged period, :func:`servo_toolkit.core.spectra.periodic_h1`, as ``frf`` estimates) is
compared with the linear plant's motor speed per current as the drive samples both at its control
instants (:func:`servo_toolkit.plant.sampled.drive_plant_response`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ...core.spectra import periodic_h1
from ...errors import SceneError, SimulationError, StrokeEndReached
from ...plant.linear import DEFAULT_STRUCTURAL_DAMPING
from ...plant.sampled import drive_plant_response
from ..multisine.run import TABLE_PER_HIGHEST
from .drive import COLUMNS, INPUTS, UNITS, drive_controller, linear_loop, periodic_response
from .levels import HEADROOM, backlash_amplitude, bounds, breakaway_current
from .plan import DEFAULT_PERIODS, default_band, default_resolution, make_plan, settle_periods
from .result import ExcitationResult
from .signals import chirp, multisine, prbs

#: a run whose current or voltage peak passes this fraction of its limit is too large: a chosen
#: amplitude is lowered to bring it back to the headroom, a given one refused
RUN_FRACTION = 0.9
#: the scene key of each limit
_LIMIT_KEYS = {"current": "motor.current_limit", "voltage": "motor.voltage_limit", "stroke": "drivetrain"}
#: runs tried while lowering a chosen amplitude
MAX_RUNS = 5
#: a run's peak this close to its limit is the clamp's: the demand beyond it is unknown, the
#: amplitude is halved
AT_CLAMP = 0.999


def signal_shape(plan, seed: int = 0) -> np.ndarray:
    """One period of the plan's signal, peak 1."""
    if plan.signal == "prbs":
        return prbs(plan.bits, plan.clock, seed)
    if plan.signal == "chirp":
        return chirp(int(plan.lines[0]), int(plan.lines[-1]), plan.period_samples)
    return multisine(plan.lines, plan.period_samples, seed)


def _crossover(design_result) -> float:
    """The loop's lowest gain crossover (Hz), else its bandwidth."""
    m = design_result.margins
    found = [f for f in m.gain_crossover_hz if f > 0 and math.isfinite(f)]
    if found:
        return min(found)
    if m.bandwidth_hz > 0 and math.isfinite(m.bandwidth_hz):
        return m.bandwidth_hz
    raise SceneError("--band", "the loop has no gain crossover nor bandwidth to centre the band on: give --band LO:HI")


def _operating_current(model) -> float:
    """The current of the model's equilibrium at its start (the operating point)."""
    from ...sim import Reference, initial_state
    from ...sim.reference import fill
    return float(initial_state(model, fill(model, Reference()))[4])


def _motion_amplitude(omega_m, resolution_hz: float, ratio: float) -> np.ndarray:
    """The motor side's periodic motion at the output (rad, or m) from its speed (rad/s)."""
    spectrum = np.fft.rfft(omega_m)
    k = np.arange(spectrum.size)
    with np.errstate(divide="ignore", invalid="ignore"):
        motion = np.where(k > 0, spectrum / (2j * math.pi * k * resolution_hz * ratio), 0.0)
    return np.fft.irfft(motion, omega_m.size)


def _run(scene, model, plan, excitation):
    """The model's run of the whole excitation from rest at the operating point: the table
    starts with a zero, then each sample is held one sample time (the drive's reference)."""
    from ...sim import Reference, run
    values = np.concatenate([[0.0], np.tile(excitation, plan.settle + plan.periods)])
    ref = Reference.table(np.arange(values.size) * plan.sample_time, values)
    return run(model, ref, plan.samples * plan.sample_time, "rk4", output_dt=plan.sample_time)


def _log(scene, res, plan, excitation, column) -> dict:
    """The file's columns: row j is the drive's sample j (the model's record j + 1)."""
    from ...sim.result import shown_name
    n = plan.samples
    drive = scene.drivetrain
    p_all = res.trace("motor_side_angle_rad")
    sign = 1.0 if float(drive.ratio([p_all[0]])[0][0]) > 0 else -1.0  # the model's motor turns positive with q
    motor = sign * (drive.kinematics(p_all[1:n + 1]).motor.value - drive.kinematics(p_all[:1]).motor.value[0])
    return {"time_s": np.arange(n) * plan.sample_time,
            column: np.tile(excitation, plan.settle + plan.periods),
            "current_A": res.motor_current[1:n + 1], "voltage_V": res.motor_voltage[1:n + 1],
            "motor_angle_rad": motor, "motor_speed_rad_s": res.motor_speed[1:n + 1],
            shown_name("output_angle_rad", drive.output_unit): res.output_angle[1:n + 1]}


def excite(scene, *, signal: str = "multisine", input: str = "current", band=None, resolution: float | None = None,
           periods: int = DEFAULT_PERIODS, settle: int | None = None, amplitude: float | None = None, seed: int = 0,
           options=None, design_result=None) -> ExcitationResult:
    """An excitation for the rig's drive, its amplitude within the scene's limits, and the
    model's run of it.

    Parameters
    ----------
    scene : Scene
    signal : {"multisine", "prbs", "chirp"}
    input : {"current", "speed"}
        What the drive takes: a current added to its position loop's current reference, or
        a motor-speed reference of its speed loop (:mod:`.drive`).
    band : (float, float), optional
        Frequencies of interest (Hz); default a decade around the loop's crossover, up to
        twice the first drivetrain mode (:mod:`.plan`).
    resolution : float, optional
        Frequency resolution (Hz): the period is its inverse, rounded up to whole samples.
        Default: five lines across the first mode's half-power bandwidth, at most the band's
        low end.
    periods : int
        Periods averaged.
    settle : int, optional
        Periods run first (default: five time constants of the drive's linear loop's slowest
        pole, at least one).
    amplitude : float, optional
        The excitation's peak (A, or motor rad/s); default the largest within
        :data:`~.levels.HEADROOM` of the current, voltage and stroke limits.
    seed : int
        The PRBS register's start; the multisine's random-phase starts.
    options : ModelOptions, optional
        The model's options (default: the structural damping the design assumes).
    design_result : DesignResult, optional
        The scene's loop design (default :func:`servo_toolkit.loop.design.design`).

    Returns
    -------
    ExcitationResult

    Raises
    ------
    SceneError
        Naming the option: a signal, input, band, resolution or periods outside their rules
        (:func:`.plan.make_plan`), speed without a speed loop, an amplitude beyond a limit
        (predicted, or in the model's run).
    SimulationError
        The drive's loop is unstable, or the model's run fails.
    """
    from ...loop.design import design
    from ...plant.linear import two_mass_damping
    from ...sim import ModelOptions, build_model

    start = time.perf_counter()
    if input not in INPUTS:
        raise SceneError("--input", f"must be one of {', '.join(INPUTS)} (got {input!r})")
    if amplitude is not None and not (math.isfinite(amplitude) and amplitude > 0):
        raise SceneError("--amplitude", f"must be a positive peak in {UNITS[input]} (got {amplitude:g})")
    result = design_result or design(scene, progress=False)
    p = result.parameters
    q0, notes = p.q0, []
    ts = float(scene.sensors.sample_time or 0.0)
    if band is None:
        band, band_notes = default_band(_crossover(result), p.resonance_hz, ts or 1e-300)
        notes += band_notes
    if ts == 0:
        ts = 1.0 / (TABLE_PER_HIGHEST * band[1])
        notes.append(f"the scene gives no sample time: the excitation is sampled at {1 / ts:.4g} Hz "
                     f"({TABLE_PER_HIGHEST} samples a period of its highest frequency), the drive's loop at that rate")
    zeta = two_mass_damping(scene.drivetrain.chain, q0, DEFAULT_STRUCTURAL_DAMPING)
    res = resolution if resolution is not None else default_resolution(band, p.resonance_hz, zeta)
    draft = make_plan(signal, band, res, periods, 0 if settle is None else settle, ts)
    linear_drive = drive_controller(result, input, ts, held=False)
    sys, decay = linear_loop(scene, linear_drive, q0, DEFAULT_STRUCTURAL_DAMPING)
    plan = make_plan(signal, band, res, periods, settle_periods(decay, draft.period_s) if settle is None else settle,
                     ts)
    shape = signal_shape(plan, seed)
    per = periodic_response(sys, shape, plan.resolution_hz)
    options = options or ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING)
    model = build_model(scene, drive_controller(result, input, ts, held=True), options)
    notes += [n for n in model.notes if "anti-windup" not in n]
    i0 = _operating_current(model)
    motor = scene.motor
    lo_s, hi_s = scene.drivetrain.stroke
    excursion = per[3] if input == "current" else per[3] - per[3][0]
    # each held sample steps the current reference by D0 (the drive's feedthrough) times the
    # excitation's step; the current loop answers at once with kp times it (the linear loop's
    # delay smooths that away)
    feedthrough = float(np.asarray(linear_drive.motion.D)[0, 0])
    kick = result.controller.current_kp * feedthrough * (shape - np.roll(shape, 1))
    shapes = {"current": per[0], "voltage": per[1] + kick, "excursion": excursion}
    limits = {"current": motor.current_limit, "voltage": motor.voltage_limit,
              "stroke_room": min(hi_s - q0, q0 - lo_s)}
    found = bounds(shapes, i0, motor.resistance, limits)
    a, binding = _amplitude(amplitude, found, shapes, i0, motor.resistance, limits, UNITS[input])
    source = "chosen" if amplitude is None else "given"
    run, a, peak_i, peak_v = _run_within_limits(scene, model, plan, shape, a, source, UNITS[input], notes)
    excitation = a * shape
    log = _log(scene, run, plan, excitation, COLUMNS[input])
    f = plan.frequency_hz
    try:
        est = periodic_h1(1.0 / ts, log["current_A"], log["motor_speed_rad_s"], plan.period_samples,
                          settle=plan.settle, lines=plan.lines)
        run_plant, coherence = est.response, est.coherence
    except (ValueError, LookupError) as exc:  # a current that does not vary (an amplitude lost in rounding)
        run_plant, coherence = np.full(f.size, complex(np.nan, np.nan)), np.full(f.size, np.nan)
        notes.append(f"no estimate of the plant from the run: {exc}")
    half_play = 0.5 * float(scene.drivetrain.backlash([q0])[0]) if not scene.drivetrain.chain.rigid else 0.0
    motion = _motion_amplitude(per[2], plan.resolution_hz, p.N)
    out = ExcitationResult(
        scene=scene.name, input=input, plan=plan, shape=shape,
        amplitude=a, amplitude_source=source, binding=binding.name if binding is not None else "", bounds=found,
        operating_current_A=i0, linear_peak_current_A=float(np.max(np.abs(i0 + a * per[0]))),
        linear_peak_voltage_V=float(np.max(np.abs(motor.resistance * i0 + a * shapes["voltage"]))),
        run_peak_current_A=peak_i, run_peak_voltage_V=peak_v,
        run_excursion=float(np.max(np.abs(run.output_angle - q0))), current_limit_A=motor.current_limit,
        voltage_limit_V=motor.voltage_limit, breakaway_current_A=breakaway_current(scene, q0),
        current_swing_A=float(a * np.max(np.abs(per[0]))), half_play=half_play,
        motion_amplitude=float(0.5 * a * np.ptp(motion)), backlash_amplitude=backlash_amplitude(half_play),
        linear_plant=drive_plant_response(scene, f, q0, DEFAULT_STRUCTURAL_DAMPING, sample_time=ts,
                                          current_gains=(result.controller.current_kp, result.controller.current_ki)),
        run_plant=run_plant,
        coherence=coherence, log=log, controller=model.controller, notes=tuple(notes),
        output_unit=scene.drivetrain.output_unit, wall_s=time.perf_counter() - start, steps=_steps(scene))
    return _with_level_notes(out)


def _steps(scene) -> dict:
    """The step the scene's encoders round each logged angle to (rad, or m for a travel), by
    the log's column; a sensor read ideally has none."""
    from ...sim.result import shown_name
    drive, sensors = scene.drivetrain, scene.sensors
    out = {}
    if sensors.motor_encoder_counts:
        out["motor_angle_rad"] = 2 * math.pi / sensors.motor_encoder_counts
    count = sensors.output_count(drive.output_is_linear)
    if count:
        out[shown_name("output_angle_rad", drive.output_unit)] = count
    return out


def _amplitude(given, found, shapes, i0: float, resistance: float, limits: dict, unit: str):
    """``(amplitude, binding Bound or None)``: the largest within the headroom, or the given
    one if no limit's prediction refuses it."""
    if given is None:
        binding = min(found, key=lambda b: b.amplitude)
        if not binding.amplitude > 0:
            raise SceneError(_LIMIT_KEYS[binding.name], f"the operating point takes {binding.operating:.4g} of the "
                             f"{binding.limit:.4g} limit: no room for an excitation within {HEADROOM * 100:.0f} % of it")
        return binding.amplitude, binding
    for b in bounds(shapes, i0, resistance, limits, fraction=1.0):
        if given > b.amplitude:
            raise SceneError("--amplitude", f"{given:.4g} {unit} peak takes the predicted {b.name} beyond its limit "
                             f"(at most {b.amplitude:.4g} {unit}; {min(x.amplitude for x in found):.4g} {unit} "
                             f"keeps every limit within {HEADROOM * 100:.0f} %)")
    return float(given), None


def _run_within_limits(scene, model, plan, shape, a: float, source: str, unit: str, notes: list):
    """The model's run at amplitude ``a``, lowered (``source`` "chosen") until its current
    and voltage stay within :data:`RUN_FRACTION` of their limits and it stays in the stroke,
    or refused (``"given"``). Returns ``(run, amplitude, peak current, peak voltage)``."""
    motor = scene.motor
    attempt = 0
    while True:
        attempt += 1
        last = attempt == MAX_RUNS
        try:
            run = _run(scene, model, plan, a * shape)
        except StrokeEndReached as exc:
            if source == "given":
                raise SceneError("--amplitude", f"{a:.4g} {unit} peak: the model's run leaves the stroke ({exc})") \
                    from None
            if last:
                raise
            a *= 0.5
            notes.append(f"amplitude halved to {a:.4g} {unit}: the model's run left the stroke at the larger one")
            continue
        peak_i = float(run.peaks.get("max_abs_current_A", np.max(np.abs(run.motor_current))))
        peak_v = float(np.max(np.abs(run.motor_voltage)))
        used = {"current": peak_i / motor.current_limit, "voltage": peak_v / motor.voltage_limit}
        name = max(used, key=used.get)
        if used[name] <= RUN_FRACTION:
            return run, a, peak_i, peak_v
        if source == "given":
            raise SceneError("--amplitude", f"{a:.4g} {unit} peak: in the model's run the {name} reaches "
                             f"{used[name]:.1%} of its limit (the linear prediction leaves out the losses, the held "
                             "samples' steps and the start); give a smaller one")
        if last:
            raise SimulationError(f"the model's run keeps the {name} at {used[name]:.1%} of its limit after "
                                  f"{MAX_RUNS} runs lowering the amplitude")
        a *= 0.5 if used[name] >= AT_CLAMP else HEADROOM / used[name]
        notes.append(f"amplitude lowered to {a:.4g} {unit}: the model's run took the {name} to {used[name]:.1%} of "
                     "its limit")


def _with_level_notes(out: ExcitationResult) -> ExcitationResult:
    from dataclasses import replace
    return replace(out, notes=out.notes + tuple(out.notes_on_levels()) + tuple(out.notes_on_response()))


__all__ = ["excite", "signal_shape"]
