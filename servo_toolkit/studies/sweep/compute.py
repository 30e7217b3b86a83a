"""Frequency-response sweep of the nonlinear closed loop by sine dwell, against the linear loop.

At each frequency (and each amplitude) the compiled closed-loop model is driven by a sine
position command ``a sin(2 pi f t)`` about mid-stroke; after the settling time the output
angle's fundamental is estimated by correlation (:mod:`.sine_dwell`). The ratio to ``a`` is
the describing-function response of the loop, compared on one Bode plot with the design's
linear loop, :func:`servo_toolkit.loop.linear_closed_loop` with the same structural damping.
The linear loop scales the motor torque by the driving-mode drivetrain efficiency; the
nonlinear model's LossyGear-like loss (:mod:`servo_toolkit.sim.model`) passes eta where the
motor drives the load and 1/eta_b where the load drives the motor, so a free sine, whose
power flow reverses every quarter period, departs from the linear loop by what that
reversal changes (noted when the chain has losses).
Amplitude dependence (backlash, voltage and current limits) shows as one curve per
amplitude; points where a limit was reached are flagged.

By default the sweep runs the reduced model of :mod:`.reduce_estimates` (effects whose
a-priori influence on this study is below the tolerance are left out) and records what was
left out; ``full=True`` runs the full model.
"""

from __future__ import annotations

import math
import re
import time

import numpy as np

from ...errors import SimulationError
from ...core.units import argument_values
from ...core.parallel import run_cases
from ...plant.linear import DEFAULT_STRUCTURAL_DAMPING
from ..sine_dwell import DwellPlan, dwell_estimate
from .points import DEFAULT_AMPLITUDE, DEFAULT_FREQUENCY_HZ, study_points
from .result import SweepResult


def _dwell_case(case):
    """One sine dwell (module level so that executors can pickle it)."""
    from ...sim import Reference, run
    model, amp, freq, plan, decay, method, limits = case
    settle, est = plan.cycles(freq, decay)
    start = time.perf_counter()
    try:
        # a quarter cycle beyond the window, so that the records cover its end
        res = run(model, Reference.sine(amp, freq), (settle + est + 0.25) / freq, method)
    except SimulationError as exc:
        i_peak, v_peak = _peaks_before_failure(model, amp, freq, method, str(exc))
        sat = i_peak >= limits[0] * (1 - 1e-9) or v_peak >= limits[1] * (1 - 1e-9)
        return {"response": complex(math.nan, math.nan), "change": math.nan, "saturated": bool(sat),
                "peak_current_A": i_peak, "peak_voltage_V": v_peak, "error": str(exc),
                "wall_s": time.perf_counter() - start}
    y = res.output_angle - model.q0
    phasor, change = dwell_estimate(res.times, y, freq, settle, est)
    window = res.times >= settle / freq
    i_peak = float(np.max(np.abs(res.current_reference[window])))
    v_peak = float(np.max(np.abs(res.motor_voltage[window])))
    sat = i_peak >= limits[0] * (1 - 1e-9) or v_peak >= limits[1] * (1 - 1e-9)
    return {"response": phasor / amp, "change": change, "saturated": bool(sat), "peak_current_A": i_peak,
            "peak_voltage_V": v_peak, "error": None, "wall_s": time.perf_counter() - start}


def _peaks_before_failure(model, amp, freq, method, message):
    """Peaks of |i_ref| and |v| (NaN if unknown) of a failed dwell up to its failure.

    The run is repeated up to 99 % of the failure time named in the message ("at t = ... s"),
    so that a point that reached the current or voltage limit before failing is flagged.
    """
    from ...sim import Reference, run
    found = re.search(r"at t = ([0-9.eE+-]+) s", message)
    t_fail = float(found.group(1)) if found else 0.0
    if not t_fail > 0:
        return math.nan, math.nan
    try:
        res = run(model, Reference.sine(amp, freq), 0.99 * t_fail, method)
    except (SimulationError, ValueError):
        return math.nan, math.nan
    return float(np.max(np.abs(res.current_reference))), float(np.max(np.abs(res.motor_voltage)))


def linear_response(scene, controller, frequencies_hz, structural_damping=DEFAULT_STRUCTURAL_DAMPING):
    """theta/theta_ref of :func:`servo_toolkit.loop.linear_closed_loop` at the design's
    operating point (where the simulation starts) at the frequencies (complex array) and the
    slowest decay rate of its poles (1/s)."""
    import control as ct

    from ...loop import linear_closed_loop
    from ...drivetrain.operating_point import operating_point
    cl = linear_closed_loop(scene, controller, q0=operating_point(scene)[0], structural_damping=structural_damping)
    sub = cl[cl.output_labels.index("theta"), cl.input_labels.index("theta_ref")]
    w = 2 * np.pi * np.asarray(frequencies_hz, dtype=float)
    resp = np.asarray(ct.frequency_response(sub, w).complex).reshape(-1)
    poles = cl.poles()
    decay = float(np.min(-poles.real)) if poles.size else math.inf
    if not decay > 0:
        worst = poles[np.argmax(poles.real)]
        raise SimulationError(
            f"the closed loop of this controller is not stable (its rightmost pole at {worst.real:.4g} "
            f"{worst.imag:+.4g}j 1/s): a physical verdict on the design, not a failure of the run; a sine dwell "
            "has no steady state to measure (servo-toolkit check fails the row closed_loop_stable, "
            "servo-toolkit design says why)")
    return resp, decay


def sweep(scene, study=None, *, frequencies=None, amplitudes=None, controller=None, options=None,
          full: bool = False, plan: DwellPlan | None = None, method: str = "rk4", executor=None,
          progress: bool = True, controller_source: str | None = None) -> SweepResult:
    """Sine-dwell frequency response of the scene's closed loop.

    Every frequency must be one a dwell resolves (:func:`.points.check_sweep_frequencies`:
    at most a quarter of the controller's sample rate, and a dwell within one run's step
    budget), else SceneError naming ``frequencies`` (given) or ``studies.NAME.frequencies``.

    Parameters
    ----------
    scene : Scene
    study : str or Study, optional
        A ``frequency_sweep`` study (8 Hz is added to its frequencies); default the scene's
        first one (see :func:`study_points`).
    frequencies : sequence of float or pint.Quantity, optional
        Hz, replacing the study's (a Quantity is converted).
    amplitudes : sequence of float or pint.Quantity, optional
        Command amplitudes (rad, or m for an output travel; a Quantity is converted),
        replacing the study's; one curve each.
    controller : CascadeController, optional
        Default: the designed loop (:func:`servo_toolkit.sim.controller_for`).
    options : ModelOptions, optional
        Run exactly these model options (no reduction).
    full : bool
        Run the full model instead of the reduced one.
    plan : DwellPlan, optional
    method : str
        Integration method of :func:`servo_toolkit.sim.run`.
    executor : concurrent.futures.Executor, optional
        Runs the dwells in parallel (see :func:`servo_toolkit.core.parallel.run_cases`).
    progress : bool
        tqdm progress bar.
    controller_source : str, optional
        Where a given ``controller`` came from, noted as ``controller from SOURCE`` (the
        caller designed it once); None: no note for a given controller.

    Returns
    -------
    SweepResult
    """
    from ...sim import controller_for
    from ..model_setup import model_setup

    start = time.perf_counter()
    name, freqs, amps = study_points(scene, study)
    if frequencies is not None:
        freqs = tuple(argument_values(frequencies, "Hz", "frequencies"))
    if amplitudes is not None:
        amps = tuple(argument_values(amplitudes, ("rad", "m"), "amplitudes"))
    if not freqs or not amps or min(freqs) <= 0 or min(amps) <= 0:
        raise ValueError("frequencies and amplitudes must be non-empty and positive")
    freqs_arr = np.asarray(sorted(freqs))
    plan = plan or DwellPlan()
    from .points import check_sweep_frequencies
    check_sweep_frequencies(scene, freqs_arr, "frequencies" if frequencies is not None
                            else f"studies.{name}.frequencies" if name else "frequency", plan)
    source = controller_source
    if controller is None:
        controller, source = controller_for(scene)
    setup = model_setup(scene, controller, freqs_arr, amps, options=options, full=full, source=source)
    options, model, reduced, left_out = setup.options, setup.model, setup.reduced, setup.left_out
    notes = list(setup.notes)
    lin, decay = linear_response(scene, controller, freqs_arr, options.damping_ratio)
    grid = np.unique(np.concatenate([np.geomspace(freqs_arr[0] / 1.5, freqs_arr[-1] * 1.5, 300), freqs_arr]))
    lin_grid, _ = linear_response(scene, controller, grid, options.damping_ratio)
    eta = scene.drivetrain.efficiency
    if eta < 1 and options.efficiency:
        notes.append(f"linear loop: the design's, with the driving-mode efficiency {eta:.3g} on the motor "
                     f"torque; the nonlinear model passes it while the motor drives the load and "
                     f"1/{scene.drivetrain.backdrive_efficiency:.3g} while the load drives the motor")
    limits = (scene.motor.current_limit, scene.motor.voltage_limit)
    cases = [(model, a, f, plan, decay, method, limits) for a in amps for f in freqs_arr]
    out = run_cases(_dwell_case, cases, executor=executor, progress=progress, description="sine dwell")
    shape = (len(amps), freqs_arr.size)

    def col(key, dtype=float):
        return np.array([o[key] for o in out], dtype=dtype).reshape(shape)

    opts = {k: v for k, v in options.__dict__.items()}
    return SweepResult(scene=scene.name, study=name, frequencies_hz=freqs_arr,
                       amplitudes_rad=np.asarray(amps, dtype=float), response=col("response", complex),
                       linear_response=lin, linear_grid_hz=grid, linear_grid_response=lin_grid,
                       settling_change=col("change"), saturated=col("saturated", bool),
                       peak_current_A=col("peak_current_A"), peak_voltage_V=col("peak_voltage_V"),
                       errors=tuple(o["error"] for o in out), reduced=reduced, left_out=left_out,
                       options=opts, plan=plan, decay_rate=decay, controller=model.controller,
                       method=method, wall_s=time.perf_counter() - start, notes=tuple(notes),
                       output_unit=scene.drivetrain.output_unit)


__all__ = ["DEFAULT_AMPLITUDE", "DEFAULT_FREQUENCY_HZ", "SweepResult", "linear_response", "study_points", "sweep"]
