"""The work budget: a long run is estimated before it starts and refused beyond it.

Every cost constant lives here, calibrated from the benchmarks (``docs/benchmarks.md``) and
measurements on the 2-core reference machine; the estimates are deliberately simple
(steps x states x variants x a per-unit cost) and err low, so that a refused run would
really have taken longer than the budget. The command line checks the budget before any
work (``--force`` lifts it); the library's study functions run what they are asked to run
(a caller from Python has chosen the size).

Memory needs no budget of its own: no array grows with an input without a bound. A time run
keeps at most ``sim.fixed_run.MAX_RECORDS`` records, the Monte Carlo keeps figures (not traces)
of at most 1,000,000 variants and steps them in chunks, the robustness margins evaluate their
frequency grid chunk by chunk, and a sweep or Kv grid is refused by its run time long before
its tables could fill the memory.
"""

from __future__ import annotations

import math

from ..errors import SceneError

#: estimated run time a command may take without ``--force`` (s): 10 min on 2 cores
TIME_BUDGET_S = 600.0

#: one fixed RK4 step per state of the model (s): 5.7 M steps/s of the 12-state reference
#: EMA on one core (bench_simulate), rounded down in cost
RK4_STATE_STEP_S = 1.2e-8
#: one controller sample of the stiff reference solver (a ``solve_ivp`` restart, s): about
#: 8,700 per second on the reference EMA
REFERENCE_SEGMENT_S = 1.1e-4
#: one variant-step of the batched Monte Carlo (s): 10,000 variants of 10,000 steps in 6.4 s
#: end to end on the 2 cores (bench_montecarlo)
BATCH_VARIANT_STEP_S = 6.4e-8
#: one variant of the vectorized linear margins (``robustness``, s): 20,000 variants in 3.3 s
LINEAR_VARIANT_S = 1.6e-4
#: one variant of a robust design's search over the variants (s), on top of its margins
ROBUST_DESIGN_VARIANT_S = 7e-4
#: one time sample of one stage's inverse dynamics in a Kv grid (s)
KV_SAMPLE_STAGE_S = 6e-7
#: one row of a closed-loop log per fitted parameter (s): the EMPS rig's 3001-row log with
#: four parameters fits in about 20 s (tests/test_identify_loop.py); a lower bound, a noisier
#: log takes more evaluations
FIT_LOOP_ROW_PARAM_S = 1.5e-3
#: settling + estimation cycles of a sine dwell at least (:mod:`.studies.sine_dwell`)
DWELL_CYCLES = 8
#: the loop's margins on the n-mass plant, every drivetrain mode (``loop.chain_margins``), per
#: cubed mode count (s): the design of a chain of 8, 12, 16 and 20 modes took 8, 27, 61 and 260 s
#: on the 2-core machine (about 0.015 s per cubed mode, faster than the cube beyond); a fifth
CHAIN_MODE3_S = 3e-3


def minutes(seconds: float) -> str:
    """A duration for a message: ``"42 s"``, ``"17 min"``, ``"3.2 h"``, ``"1.2e+05 h"``."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    hours = seconds / 3600
    return f"{hours:.1f} h" if hours < 1e4 else f"{hours:.2g} h"


def check_time(seconds: float, knob: str, what: str, got, force: bool = False) -> None:
    """Refuse an estimated run time beyond :data:`TIME_BUDGET_S` unless ``force``.

    Parameters
    ----------
    seconds : float
        The estimate.
    knob : str
        The scene key or option that sets the size of the work (named in the message).
    what : str
        What the estimate counts, e.g. ``"1e+12 RK4 steps of 12 states"``.
    got : object
        The knob's value, shown as ``(got ...)``.
    force : bool
        Run anyway (``--force``).

    Raises
    ------
    SceneError
        ``knob: the run is estimated at ... (what), beyond the budget of 10 min; ... (got X)``.
    """
    if force or not (seconds > TIME_BUDGET_S or math.isnan(seconds)):
        return
    raise SceneError(knob, f"the run is estimated at {minutes(seconds)} ({what}), beyond the budget of "
                           f"{minutes(TIME_BUDGET_S)} on 2 cores; reduce it or give --force (got {got})")


def model_states(scene) -> int:
    """States of a scene's full nonlinear model, about: two per inertia node of the chain
    (angle and speed) plus the current and the controller's."""
    return 2 * (len(scene.stages) + 1) + 6


def time_run_seconds(scene, duration: float, dt: float | None, method: str | None) -> tuple[float, str, float]:
    """A lower bound of a time run's cost: ``(seconds, what, steps)``.

    A fixed-step run takes at least ``duration / dt`` steps and, with a sampled controller,
    at least one per sample; the reference solver restarts at every sample.
    """
    ts = float(scene.sensors.sample_time or 0.0)
    nx = model_states(scene)
    if method == "reference":
        if ts > 0:
            seg = duration / ts
            return seg * REFERENCE_SEGMENT_S, f"{seg:.3g} reference-solver segments", seg
        return 0.0, "", 0.0
    step = min(x for x in (dt, ts or None, duration) if x)
    steps = duration / step
    return steps * nx * RK4_STATE_STEP_S, f"{steps:.3g} RK4 steps of {nx} states", steps


#: a run longer than this (s) is "long": its duration, not its step, is the knob named
LONG_RUN_S = 10.0


#: Kv grid: inertial-force evaluations per case (motion x inertia) of the peak search, and
#: the cost of one per squared stage count (each evaluation composes the chain's Jacobians
#: stage by stage; 0.07 s at 154 stages)
KV_CALLS_PER_CASE = 150
KV_CALL_STAGE2_S = 2.5e-6
#: one sweep point's fixed cost (model, linear response, dwell set-up; s): 21 points in 9 s
SWEEP_POINT_S = 0.3


def design_seconds(scene) -> tuple[float, str]:
    """A lower bound of a loop design's (or evaluation's) cost on a chain of many compliances:
    its margins on the n-mass plant, whose crossings are searched on the response of every
    mode (0 for a scene without a motor-driven chain of two or more modes)."""
    if not scene.stages or scene.motor is None or scene.mechanism is not None:
        return 0.0, ""
    from ..drivetrain.chain_damping import kept_nodes
    drive = scene.drivetrain
    if drive.chain.rigid:
        return 0.0, ""
    modes = int(kept_nodes(drive.chain, drive.mid_stroke).size) - 1
    return modes ** 3 * CHAIN_MODE3_S, f"the loop's margins on the n-mass plant of {modes} drivetrain modes"


def kv_seconds(stages: int, cases: int) -> tuple[float, str]:
    """A Kv grid of ``cases`` (motion x load inertia) on a chain of ``stages``."""
    seconds = cases * KV_CALLS_PER_CASE * stages ** 2 * KV_CALL_STAGE2_S
    return seconds, f"{cases} cases on a chain of {stages} stages"


def batch_seconds(scene, samples: int, duration: float) -> tuple[float, str]:
    """A batched Monte Carlo of ``samples`` variants for ``duration`` seconds (a step of at
    most the sample time)."""
    ts = float(scene.sensors.sample_time or 0.0) or duration / 200
    steps = max(duration / ts, 1.0)
    return samples * steps * BATCH_VARIANT_STEP_S, f"{samples} variants x {steps:.3g} steps"


def robustness_seconds(scene, spec, robust_design: bool) -> tuple[float, str]:
    """A ``[robustness]`` study: the linear margins of every variant, a robust design's
    search over them, and the nonlinear runs of its time-run requirements."""
    n = int(spec.samples)
    seconds = n * (LINEAR_VARIANT_S + (ROBUST_DESIGN_VARIANT_S if robust_design else 0.0))
    what = f"{n} variants" + (" of a robust design" if robust_design else "")
    if getattr(spec, "max_tracking_error", None) is not None or getattr(spec, "max_peak_current", None) is not None:
        s, w = batch_seconds(scene, n, 1.0)
        seconds += s
        what += f" and {w} of nonlinear runs"
    return seconds, what


def tolerance_seconds(scene, samples: int, nonlinear: bool, duration: float = 1.0, sobol_runs: int = 0
                      ) -> tuple[float, str]:
    """A tolerance study of ``samples`` variants: their linear margins and, when
    ``nonlinear``, a batched time run of ``duration`` seconds each (and ``sobol_runs (d + 2)``
    further runs for the Sobol indices, d the number of tolerances)."""
    n = int(samples)
    seconds, what = n * LINEAR_VARIANT_S, f"{n} variants"
    if nonlinear:
        d = len(getattr(scene.tolerances, "items", ()) or ())
        runs = n + int(sobol_runs) * (d + 2)
        s, w = batch_seconds(scene, runs, duration)
        seconds += s
        what += f" and {w} of nonlinear runs"
    return seconds, what


def fit_seconds(rows: int, params: int) -> tuple[float, str]:
    """A fit to a closed-loop log of ``rows`` rows: the nonlinear closed loop run over the log
    for every evaluation of the least-squares search over ``params`` parameters."""
    return rows * max(int(params), 1) * FIT_LOOP_ROW_PARAM_S, f"{rows} rows x {params} parameters of closed-loop runs"


def sweep_seconds(scene, frequencies, amplitudes, runs: int = 1) -> tuple[float, str]:
    """Sine dwells at every frequency and amplitude (``runs`` models each): a fixed cost per
    point plus :data:`DWELL_CYCLES` cycles of RK4 steps at most the sample time."""
    ts = float(scene.sensors.sample_time or 0.0)
    nx = model_states(scene)
    points = len(frequencies) * len(amplitudes) * runs
    steps = sum(DWELL_CYCLES / f / ts if ts > 0 else DWELL_CYCLES * 200 for f in frequencies if f > 0)
    seconds = points * SWEEP_POINT_S + steps * len(amplitudes) * runs * nx * RK4_STATE_STEP_S
    return seconds, f"{points} sine dwells"
