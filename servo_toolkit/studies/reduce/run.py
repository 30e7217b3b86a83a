"""Leave out what a study does not need: the reduced model, why, and its measured error.

:func:`reduce` judges every modelled effect against a study's frequencies and amplitudes
(:func:`.estimates.plan_reduction`: numbers, a-priori error estimates, the choice),
then runs the study on the full model (every effect kept, friction that holds included) and on
the reduced model (the options the plan chose, which the study's own runs use) and measures
their difference (nothing left out: the two are one model, run once), and
measures the cost of each effect left out on its own: one more run of the study on the full
model with only that effect's switch changed, compared with the full model the same way. The
chain's modes above the first are measured so whether ``simulate``'s rule lumps them or not
(the full chain against its two-mass reduction: the measurement checks the rule's estimate):

- a ``frequency_sweep`` study: the sine-dwell responses of both models (:func:`.sweep.sweep`),
  difference ``|H_reduced / H_full - 1|`` per point;
- a ``kv`` or ``simulate`` study with a sine motion: the output-angle traces of both models
  over the steady part of the run, difference ``RMS(q_reduced - q_full) / RMS(q_full - q0)``
  (for a sinusoid the same measure as above, plus any harmonics).

The a-priori bound is the reduction's tolerance (module :mod:`.estimates` explains
why it holds in the linear range); points where a run reached the current or voltage limit
are outside that statement and are reported separately. A point whose run failed on either
model (non-finite, out of its domain...) has no difference: it is reported as failed with
the run's reason, and the measured difference is over the points that ran on both models.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...errors import SceneError, SimulationError
from ...core.output_units import output_unit
from ...core.parallel import run_cases
from ...plant.linear import DEFAULT_STRUCTURAL_DAMPING
from ...scene.study_kind import study_kinds
from ..kv.kind import KV
from ..sine_dwell import DwellPlan
from ..sweep.compute import linear_response, study_points, sweep
from ..sweep.kind import SWEEP
from .choice import options_without
from .estimates import DEFAULT_TOLERANCE, plan_reduction
from .result import EffectCost, ReductionResult


def time_points(study, scene=None):
    """``(frequencies_hz, amplitudes_rad)`` of a kv or simulate study with a sine motion (the
    output's amplitudes: a kv study's motor-gear amplitudes divided by the ratio, which needs
    ``scene``)."""
    p = study.params
    if "voltage" in p:
        raise SceneError(study.key("voltage"), "an open-loop study has no closed loop to reduce")
    if p.get("trajectory", "sine") != "sine":
        raise SceneError(study.key("trajectory"), "only sine motions can be reduced")
    freq = p.get("frequency")
    if freq is None and p.get("period"):
        freq = 1.0 / p["period"]
    amps = p.get("amplitudes") or ([p["amplitude"]] if p.get("amplitude") is not None else None)
    if freq is None or not amps:
        raise SceneError(study.key("kind"), "needs a frequency (or period) and amplitude(s)")
    if scene is not None:  # a sine the sampled loop cannot track is no study to reduce for
        from ...sim.reference_checks import check_sine_frequency
        check_sine_frequency(float(freq), float(scene.sensors.sample_time), None,
                             study.key("frequency" if p.get("frequency") is not None else "period"))
    if study.kind == KV.name and p.get("amplitude_at", "output") != "output":
        if scene is None:
            raise ValueError("a kv study with amplitude_at other than 'output' needs the scene")
        from ..kv.study import output_amplitudes
        amps = output_amplitudes(scene, study, amps)
    return np.array([float(freq)]), tuple(float(a) for a in amps)


def _trace_case(case):
    """One closed-loop sine run; returns times, output angle and whether a limit was reached
    in the compared window (``t >= t_settle``, as the sweep flags its dwell window) and
    before it (the start-up transient: the command starts with its full slope)."""
    from ...sim import Reference, run
    model, amp, freq, duration, limits, t_settle = case
    try:
        # RK4 with the step it needs: shrunk where a mode stiffens along the run (an end stop)
        res = run(model, Reference.sine(amp, freq), duration, "auto")
    except SimulationError as exc:
        return {"error": str(exc)}
    hit = ((np.abs(res.current_reference) >= limits[0] * (1 - 1e-9))
           | (np.abs(res.motor_voltage) >= limits[1] * (1 - 1e-9)))
    window = res.times >= t_settle
    return {"t": res.times, "q": res.output_angle - model.q0, "saturated": bool(np.any(hit[window])),
            "startup_saturated": bool(np.any(hit[~window])), "error": None}


def _trace_difference(full, red, t_settle):
    """``(difference, saturated)`` of two runs' output traces over the compared window
    (NaN, False when either run failed: :func:`_difference` names why)."""
    if full["error"] or red["error"]:
        return math.nan, False
    keep = full["t"] >= t_settle
    q_red = np.interp(full["t"][keep], red["t"], red["q"])
    q_full = full["q"][keep]
    ref = np.sqrt(np.mean((q_full - q_full.mean()) ** 2))
    return float(np.sqrt(np.mean((q_red - q_full) ** 2)) / ref), full["saturated"] or red["saturated"]


def reduce(scene, study=None, *, tolerance: float = DEFAULT_TOLERANCE, controller=None, plan=None,
           executor=None, progress: bool = True, frequencies=None, amplitudes=None,
           per_effect=True, controller_source: str | None = None, reduction=None) -> ReductionResult:
    """Reduce the scene's model for a study and measure the reduction on that study.

    Parameters
    ----------
    scene : Scene
    study : str or Study, optional
        A ``frequency_sweep``, ``kv`` or ``simulate`` (sine) study; default the scene's sweep
        plus 8 Hz (see :func:`.sweep.study_points`).
    tolerance : float
        A-priori bound on the relative response difference between full and reduced model.
    controller : CascadeController, optional
        Default: the designed loop.
    plan : DwellPlan, optional
        Settling and estimation cycles.
    executor : concurrent.futures.Executor, optional
    progress : bool
    frequencies : sequence of float, optional
        Hz, replacing a sweep study's frequencies (8 Hz is then not added).
    amplitudes : sequence of float, optional
        Command amplitudes (rad, or m for an output travel), replacing the study's.
    per_effect : bool or sequence of str
        Also measure each effect left out on its own, and the chain's modes above the first
        (one more run of the study each); a sequence names the effects to measure so.
    controller_source : str, optional
        Where a given ``controller`` came from, noted as ``controller from SOURCE`` (the
        caller designed it once); None: no note for a given controller.
    reduction : ReductionPlan, optional
        The a-priori plan for this study's points, ``controller`` and ``tolerance`` (the
        caller judged it once, e.g. by :func:`reduced_options`); default: judged here.

    Returns
    -------
    ReductionResult

    Raises
    ------
    ValueError
        A ``reduction`` judged for other frequencies, amplitudes, tolerance or another full
        model than the study's.
    """
    from ...sim import ModelOptions, build_model, controller_for

    source = controller_source
    if controller is None:
        controller, source = controller_for(scene)
    notes = [] if source is None else [f"controller from {source}"]
    if isinstance(study, str):
        study = scene.study(study)
    if study is None or study.kind == SWEEP.name:
        name, freqs, amps = _sweep_points(scene, study, frequencies)
        freqs, measure = np.asarray(freqs), "sweep"
    elif study_kinds()[study.kind].time_run:
        _no_frequencies(study, frequencies)
        name = study.name
        freqs, amps = time_points(study, scene)
        measure = "trace"
    else:
        raise SceneError(study.key("kind"), f"is {study.kind!r}; reduce handles frequency_sweep, kv and "
                         "simulate studies")
    if amplitudes is not None:
        amps = tuple(float(a) for a in np.atleast_1d(amplitudes))
        if not amps or not all(math.isfinite(a) and a > 0 for a in amps):
            raise ValueError("amplitudes must be non-empty, positive and finite")
    stop = "stop" if measure == "trace" else "error"
    full = ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING, stroke_end=stop, chain="full", friction="stick")
    if reduction is None:
        rplan = plan_reduction(scene, controller, freqs, amps, base=full, tolerance=tolerance)
    else:
        rplan = _judged_for(reduction, full, freqs, amps, tolerance)
    reduced = rplan.options
    dwell = plan or DwellPlan()
    if measure == "sweep":
        kw = dict(frequencies=freqs, amplitudes=amps, controller=controller, plan=dwell, executor=executor,
                  progress=progress)

        def study_on(options, label):
            return sweep(scene, name, options=options, **kw)
    else:
        notes.append("time runs with an elastic stroke-end stop on every model")
        _, decay = linear_response(scene, controller, freqs, full.damping_ratio)
        f = float(freqs[0])
        settle, est = dwell.cycles(f, decay)
        limits = (scene.motor.current_limit, scene.motor.voltage_limit)

        def study_on(options, label):
            model = build_model(scene, controller, options)
            runs = run_cases(_trace_case, [(model, a, f, (settle + est) / f, limits, settle / f) for a in amps],
                             executor=executor, progress=progress, description=f"{label} model")
            return _Traces(runs, settle / f)
    s_full = study_on(full, "full")
    # nothing left out: the reduced model is the full one, and a second run would only repeat it
    s_red = s_full if reduced == full else study_on(reduced, "reduced")
    diff, sat, failures = _difference(s_full, s_red, ("full", "reduced"))
    if measure == "trace":
        notes.append(f"compared over t >= {settle / f:.3g} s of {(settle + est) / f:.3g} s "
                     f"(settling: {dwell.settling_time_constants:g} time constants of the slowest loop mode); "
                     "a point counts as saturated when a limit was reached in that window")
        early = [output_unit(scene).text(a, 3) for a, r_f, r_r in zip(amps, s_full.runs, s_red.runs)
                 if r_f.get("startup_saturated") or r_r.get("startup_saturated")]
        if early:
            notes.append(f"the start-up transient (the sine command starts with its full slope) reached a limit "
                         f"before the compared window at {', '.join(early)}; it has "
                         "decayed by then")
    costs = []
    alone = [e for e in rplan.effects if e.switch is not None and (e.omitted or e.switch == "chain")]
    if not isinstance(per_effect, bool):
        alone = [e for e in alone if e.effect in set(per_effect)]
    for effect in alone if per_effect else []:
        alone = study_on(options_without(full, [effect]), f"without {effect.effect}")
        d, s_, why = _difference(s_full, alone, ("full", f"without {effect.effect}"))
        failed = np.array([w is not None for w in why], dtype=bool).reshape(d.shape)
        costs.append(EffectCost(effect.effect, effect.estimate, _largest(d, ~s_ & ~failed), _largest(d, s_),
                                int(failed.sum())))
    return ReductionResult(scene=scene.name, study=name, measure=measure, plan=rplan, frequencies_hz=freqs,
                           amplitudes_rad=np.asarray(amps, dtype=float), difference=diff, saturated=sat,
                           failures=failures,
                           full_options=dict(full.__dict__), reduced_options=dict(reduced.__dict__),
                           notes=tuple(notes),
                           output_unit=output_unit(scene).si, per_effect=tuple(costs))


@dataclass(frozen=True)
class _Traces:
    """The closed-loop sine runs of a time study on one model (one per amplitude)."""

    runs: list
    t_settle: float


def _difference(a, b, names):
    """``(difference, saturated, failures)`` of a study run on two models named ``names``:
    difference and saturated (n_a, n_f), the sine-dwell responses' ``|H_b / H_a - 1|`` or the
    output traces' RMS difference; failures row-major, None or why a point's run failed on
    either model. A failed point has no difference (NaN) and is not counted as saturated."""
    if isinstance(a, _Traces):
        pairs = [_trace_difference(x, y, a.t_settle) for x, y in zip(a.runs, b.runs)]
        diff = np.array([[d] for d, _ in pairs], dtype=float)
        sat = np.array([[s] for _, s in pairs], dtype=bool)
        errors = zip((x["error"] for x in a.runs), (y["error"] for y in b.runs))
    else:
        with np.errstate(invalid="ignore", divide="ignore"):
            diff = np.abs(b.response / a.response - 1.0)
        sat = a.saturated | b.saturated
        errors = zip(a.errors, b.errors)
    failures = []
    for (err_a, err_b), d in zip(errors, diff.ravel()):
        why = "; ".join(f"{n} model: {e}" for n, e in zip(names, (err_a, err_b)) if e)
        if not why and not math.isfinite(d):
            why = f"no finite difference between the {names[0]} and the {names[1]} model"
        failures.append(why or None)
    failed = np.array([f is not None for f in failures], dtype=bool).reshape(diff.shape)
    return np.where(failed, math.nan, diff), sat & ~failed, tuple(failures)


def _judged_for(reduction, full, freqs, amps, tolerance):
    """``reduction`` on the study's full model ``full``, checked to be judged for the same
    points, tolerance and full model (up to its stroke end: :meth:`ReductionPlan.on`)."""
    on_full = reduction.on(full)
    same = (np.array_equal(np.asarray(reduction.frequencies_hz, float), np.sort(np.asarray(freqs, float)))
            and tuple(reduction.amplitudes_rad) == tuple(float(a) for a in amps)
            and reduction.tolerance == tolerance
            and replace(reduction.options, stroke_end=full.stroke_end) == on_full.options)
    if not same:
        raise ValueError("the reduction was judged for other frequencies, amplitudes, tolerance or full model "
                         "than this study's")
    return on_full


def _no_frequencies(study, frequencies) -> None:
    """SceneError when frequencies are given for a time study (its motion sets its own)."""
    if frequencies is not None:
        raise SceneError(study.key("kind"), f"is {study.kind!r}; frequencies replace a frequency_sweep "
                         "study's only (a time study's motion sets its frequency)")


def _largest(diff, where) -> float:
    """Largest difference over the points ``where`` (NaN: none ran on both models)."""
    ok = where & ~np.isnan(diff)
    return float(np.max(diff[ok])) if ok.any() else math.nan


def _sweep_points(scene, study, frequencies):
    """:func:`.sweep.study_points`, with ``frequencies`` (Hz) replacing the study's."""
    name, freqs, amps = study_points(scene, study)
    if frequencies is not None:
        freqs = tuple(sorted(float(f) for f in np.atleast_1d(frequencies)))
        if not freqs or not all(math.isfinite(f) and f > 0 for f in freqs):
            raise ValueError("frequencies must be non-empty, positive and finite")
    return name, freqs, amps


def reduced_options(scene, study=None, *, tolerance: float = DEFAULT_TOLERANCE, controller=None,
                    frequencies=None, amplitudes=None):
    """Only the a-priori part: ``(ModelOptions, ReductionPlan)`` for a study (no runs).

    A time simulation can adopt the reduction with
    ``simulate(scene, options=reduced_options(scene, name)[0], ...)``.
    """
    from ...sim import ModelOptions, controller_for
    if controller is None:
        controller, _ = controller_for(scene)
    if isinstance(study, str):
        study = scene.study(study)
    if study is None or study.kind == SWEEP.name:
        _, freqs, amps = _sweep_points(scene, study, frequencies)
        from ...sim.reference_checks import check_sine_frequency
        for f in freqs:
            check_sine_frequency(f, float(scene.sensors.sample_time), None,
                                 "frequencies" if frequencies is not None or study is None
                                 else study.key("frequencies"))
    elif study_kinds()[study.kind].time_run:
        _no_frequencies(study, frequencies)
        freqs, amps = time_points(study, scene)
    else:
        raise SceneError(study.key("kind"), f"is {study.kind!r}; reduce handles frequency_sweep, kv and "
                         "simulate studies")
    if amplitudes is not None:
        amps = tuple(float(a) for a in np.atleast_1d(amplitudes))
    rplan = plan_reduction(scene, controller, freqs, amps,
                           base=ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING, chain="full",
                                             friction="stick"),
                           tolerance=tolerance)
    return replace(rplan.options), rplan
