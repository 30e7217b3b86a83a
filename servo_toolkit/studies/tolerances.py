"""The tolerance study: what fraction of built actuators meets the requirements, and which
tolerance to tighten.

Variants are drawn from the scene's ``[tolerances]`` (:mod:`servo_toolkit.scene.tolerances`;
a ``[robustness]`` table's ranges count as tolerances) by Latin hypercube, scrambled Sobol or
independent draws (:func:`servo_toolkit.loop.sampling.sample_tolerances`). Each variant's
linear loop with the designed controller gives its margins
(:func:`servo_toolkit.loop.robustness.variant_figures` on plants mapped from the keys,
:mod:`servo_toolkit.loop.variant_plants`); where the scene bounds the tracking error or the
peak current, each variant also runs in time on the nonlinear model
(:mod:`.tolerance_runs`). Then:

- the *yield* of every requirement, and of all of them at once, with its Clopper-Pearson
  interval (:mod:`servo_toolkit.core.yields`); ``min_yield`` is met when the interval's lower
  end reaches it;
- the *sensitivity* of each figure to each tolerance (:mod:`servo_toolkit.core.sensitivity`:
  standardized regression where the figure is near-linear, Sobol indices where not, a key
  that does not enter the figure exactly 0);
- the *worst corner*: every corner of the tolerance box (each tolerance at an end) through
  the linear study, the one with the smallest margin to a requirement built exactly, its
  margins checked with python-control and its nonlinear closed loop run on its own.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from ..errors import SceneError, SimulationError
from ..core.sensitivity import rank, sobol
from ..core.yields import Yield
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING
from .tolerance_result import ToleranceResult, WorstCorner

#: margin requirement -> (figure of the linear study, label)
FIGURES = {"gain_margin": ("gain_margin_db", "gain margin"), "phase_margin": ("phase_margin_deg", "phase margin"),
           "sensitivity_peak": ("sensitivity_peak_db", "sensitivity peak Ms"),
           "bandwidth": ("bandwidth_hz", "closed-loop bandwidth"),
           "phase_lag_at_bandwidth": ("phase_lag_deg", "phase lag at the bandwidth")}
#: corners evaluated one by one up to this many (2**10); beyond, the regression's signs choose
MAX_CORNERS = 1024
#: base sample of the Sobol indices of a nonlinear margin figure (n (d + 2) evaluations)
SOBOL_BASE = 512


def _requirements(scene, result, tol):
    """(margin requirements, time requirements) in display units."""
    from ..loop.requirements import Requirement, robust_requirements
    from ..scene.loader import Robustness
    spec = scene.robustness or Robustness(load_inertia=None, stiffness=None)
    margins = [r for r in robust_requirements(spec, result.requirements) if r.name != "stable_fraction"]
    timed = []
    if tol.max_tracking_error is not None:
        linear = scene.drivetrain.output_is_linear
        dim = tol.tracking_error_dimension
        if dim is not None and dim != ("length" if linear else "angle"):
            raise SceneError("tolerances.max_tracking_error", f"the output is {'a travel: give a length' if linear else 'an angle: give an angle'}")
        value = tol.max_tracking_error * 1e3 if linear else math.degrees(tol.max_tracking_error)
        timed.append(Requirement("tracking_error", "<=", value, "mm" if linear else "deg", "tolerances"))
    if tol.max_peak_current is not None:
        timed.append(Requirement("peak_current", "<=", tol.max_peak_current, "A", "tolerances"))
    return margins, timed


def _meets(r, y):
    with np.errstate(invalid="ignore"):
        return (y >= r.value) if r.sense == ">=" else (y <= r.value) & np.isfinite(y)


def _relative_margin(r, y):
    """(achieved - required) / |required| in the requirement's sense (positive: met)."""
    scale = abs(r.value) if r.value else 1.0
    with np.errstate(invalid="ignore"):
        return ((y - r.value) if r.sense == ">=" else (r.value - y)) / scale


def tolerance_study(scene, result=None, *, samples: int | None = None, method: str | None = None,
                    seed: int | None = None, nonlinear: bool | None = None, executor=None, progress: bool = True,
                    worst_corner: bool = True, sobol_runs: int = 0, duration: float | None = None,
                    structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> ToleranceResult:
    """Yield and sensitivity of ``result``'s controller over the scene's tolerances.

    Parameters
    ----------
    scene : Scene
        With ``[tolerances]`` (or ``[robustness]`` ranges).
    result : DesignResult, optional
        Default: :func:`servo_toolkit.loop.design` of the scene.
    samples, method, seed : optional
        Override the ``[tolerances]`` table's.
    nonlinear : bool, optional
        Run every variant in time (default: when the scene bounds the tracking error or the
        peak current).
    executor : concurrent.futures.Executor, optional
        Runs chunks of variants (a dask ``Client.get_executor()``, a process pool); the
        results do not depend on it.
    progress : bool
    worst_corner : bool
        Find the worst corner and run it again on its own.
    sobol_runs : int
        Base sample of Sobol indices of a nonlinear time figure that standardized regression
        does not explain (``sobol_runs (d + 2)`` further time runs; 0: ranked by regression,
        stated).
    duration : float, optional
        Seconds of each time run (default: ``simulate``'s).
    structural_damping : float

    Returns
    -------
    ToleranceResult

    Raises
    ------
    SceneError
        No tolerances, a tolerance end at which the scene does not load, a variant that
        changes the model's structure.
    SimulationError
        A variant's time run could not be carried out (no verdict on its requirement).
    """
    from ..loop.robustness import variant_figures
    from ..loop.sampling import sample_tolerances
    from ..loop.variant_plants import keyed_plants
    from ..scene.tolerances import check_ends
    from .run import has_motor_drivetrain
    tol = scene.tolerances
    if tol is None:
        raise SceneError("tolerances", "the scene sets no [tolerances] (nor [robustness] ranges) to vary")
    if not has_motor_drivetrain(scene):
        raise SceneError("tolerances", "a tolerance study needs a motor-driven drivetrain ([motor] and [[drivetrain]])")
    check_ends(tol)
    if result is None:
        from ..loop import design
        result = design(scene, progress=False)
    n = tol.samples if samples is None else int(samples)
    method = method or tol.method
    seed = tol.seed if seed is None else int(seed)
    values = sample_tolerances(tol, n, method, seed)
    keys = tol.scene_keys()
    p, ctrl = result.parameters, result.controller
    f_req = next(r.required for r in result.requirements if r.name == "bandwidth")
    plants = keyed_plants(scene, p, values, structural_damping, keys=keys, progress=progress)
    figs = variant_figures(scene, p, ctrl, values, f_req, plants=plants, executor=executor, progress=progress,
                           structural_damping=structural_damping)
    margins, timed = _requirements(scene, result, tol)
    stable = figs["stable"]
    passes = {"stable": stable.copy()}
    for r in margins:
        passes[r.name] = stable & _meets(r, figs[FIGURES[r.name][0]])
    notes = [f"linear plants of the variants: {plants.method}"
             + (f" (maps verified to a relative {plants.error:.2g} against {plants.evaluations} exact builds)"
                if plants.method == "separable" else "")]
    if plants.inert:
        notes.append("not entering the linear loop (its margins do not depend on them): " + ", ".join(plants.inert))
    notes += sampling_notes(method, n)
    runs = None
    if nonlinear or (nonlinear is None and timed):
        from .tolerance_runs import tolerance_runs
        runs = tolerance_runs(scene, values, ctrl, keys=keys, executor=executor, progress=progress, duration=duration,
                              seed=seed)
        runs, physical = _judge_failed(runs, values, stable)
        notes += list(runs.notes)
        if physical.any():
            notes.append(f"{int(physical.sum())} variants fail the time requirements by their physics (the stroke "
                         f"end reached, or a run diverging with an unstable linear loop): counted as failing, left "
                         f"out of the time figures' rankings")
        shown = _time_shown(scene, runs)
        for r in timed:
            passes[r.name] = _meets(r, shown[r.name])
    if runs is None and set(plants.inert) >= set(tol.keys):
        notes.append("no tolerance enters a judged figure: every variant has the nominal design's margins, so the "
                     "yield is the nominal verdict whatever the sample; a time requirement (max_tracking_error, "
                     "max_peak_current) or --nonlinear judges what they act on")
    passes["all"] = np.logical_and.reduce(list(passes.values()))
    labels = {"stable": "closed loop stable", **{k: v[1] for k, v in FIGURES.items()},
              "tracking_error": "tracking error", "peak_current": "peak current", "all": "every requirement"}
    reqs = {r.name: r for r in margins + timed}
    yields = tuple(Yield.of(name, labels[name] + (f" {reqs[name].sense} {reqs[name].value:g} {reqs[name].unit}"
                                                   if name in reqs else ""),
                            int(ok.sum()), n, tol.confidence, tol.min_yield if name == "all" else None)
                   for name, ok in passes.items())
    sens = _sensitivities(tol, values, figs, margins, runs, timed, plants, scene, p, ctrl, f_req, structural_damping,
                          sobol_runs, seed, executor)
    worst = None
    if worst_corner:
        worst = _worst_corner(scene, tol, values, figs, margins, plants, p, ctrl, f_req, keys, structural_damping,
                              runs, duration, timed=timed if runs is not None else (), executor=executor, seed=seed)
        notes += list(worst.notes) if worst is not None else []
    notes = list(dict.fromkeys(notes))  # a note given by two parts of the model once
    settings = {"samples": n, "method": method, "seed": seed, "plants": plants.method, "plants_error": plants.error}
    return ToleranceResult(scene.name, tol, values, figs, runs, tuple(margins + timed), passes, yields, sens, worst,
                           settings, tuple(notes), scene.display, scene.drivetrain.output_is_linear)


def sampling_notes(method: str, n: int) -> list:
    """What the draws cannot promise: a scrambled Sobol sample of ``n`` not a power of 2 is
    balanced (and the yield interval's conservatism shown) only for 2^m points (scipy warns;
    the study says so in its notes)."""
    if method == "sobol" and n & (n - 1):
        return [f"a Sobol sample of {n} variants, not a power of 2: the sequence is balanced (and the yield "
                f"interval's conservatism shown) only for 2^m points; {1 << n.bit_length()} variants would "
                f"restore it"]
    return []


def _time_shown(scene, runs) -> dict:
    """The time runs' figures in the units of their requirements (deg or mm; A)."""
    return {"tracking_error": runs.tracking_error * (1e3 if scene.drivetrain.output_is_linear else 180 / math.pi),
            "peak_current": runs.peak_current}


def _physical(runs, stable) -> np.ndarray:
    """Which failed runs failed by their physics: the stroke end reached, or a divergence
    with an unstable linear loop."""
    reasons = np.array(runs.reasons, dtype=object)
    stroke = np.array([r.startswith("stroke end reached") for r in reasons], bool)
    diverged = np.array([r.startswith("non-finite state") for r in reasons], bool) & ~np.asarray(stable, bool)
    return runs.failed & (stroke | diverged)


def _judge_failed(runs, values, stable):
    """(runs, physical): the runs with the time figures of the variants that failed by
    their physics set to NaN (they fail every time requirement), and which those are: a run
    that reached the stroke end (the actuator hit its stop), or that diverged while its
    linear loop is unstable. Any other failed run (a step outside the RK4 stability region,
    no start, a stable loop's state turning non-finite) is the model's, not the design's:
    no verdict.

    Raises
    ------
    SimulationError
        Naming the first variant that failed for want of a model.
    """
    from dataclasses import replace
    physical = _physical(runs, stable)
    _refuse_failed(replace(runs, failed=runs.failed & ~physical), values)
    nan = np.where(physical, np.nan, 1.0)
    return replace(runs, tracking_error=runs.tracking_error * nan, peak_current=runs.peak_current * nan), physical


def _refuse_failed(runs, values) -> None:
    failed = np.flatnonzero(runs.failed)
    if failed.size:
        i = int(failed[0])
        at = ", ".join(f"{k}={v[i]:.4g}" for k, v in values.items())
        raise SimulationError(f"the tolerance study could not run {failed.size} of {runs.count} variants in time "
                              f"(first: variant {i}, {at}: {runs.reasons[i]}); no verdict on their requirements")


def _log_keys(tol):
    return np.array([t.distribution == "log_uniform" for t in tol.items])


def _sensitivities(tol, values, figs, margins, runs, timed, plants, scene, p, ctrl, f_req, zeta, sobol_runs, seed,
                   executor=None):
    """Ranking of the tolerances on each requirement's figure."""
    from ..loop.robustness import variant_figures
    keys = tol.keys
    X = np.column_stack([values[k] for k in keys])
    inert_linear = np.array([k in plants.inert for k in keys])
    stable = figs["stable"]
    cache = {}

    def margin_sobol(name):
        def run(live):
            if plants.mapper is None:
                return None
            if "res" not in cache:
                live_keys = [k for k, m in zip(keys, live) if m]

                def func(x):
                    vals = {k: np.full(x.shape[1], tol.item(k).nominal) for k in keys}
                    vals.update({k: x[j] for j, k in enumerate(live_keys)})
                    f = variant_figures(scene, p, ctrl, vals, f_req, plants=plants.mapper(vals), progress=False,
                                        structural_damping=zeta)
                    out = np.array([np.where(f["stable"], f[FIGURES[r.name][0]], np.nan) for r in margins])
                    for row, r in zip(out, margins):  # no figure: the sample's worst finite one
                        bad = ~np.isfinite(row)
                        if bad.any() and (~bad).any():
                            row[bad] = np.min(row[~bad]) if r.sense == ">=" else np.max(row[~bad])
                        elif bad.all():
                            row[:] = 0.0
                    return out
                cache["res"] = sobol(func, [tol.item(k) for k in live_keys], SOBOL_BASE, seed=seed,
                                     confidence=tol.confidence)
            res = cache["res"]
            j = [r.name for r in margins].index(name)
            return {k: v[j:j + 1] if isinstance(v, np.ndarray) else v for k, v in res.items()}
        return run if plants.mapper is not None else None

    out = []
    for r in margins:
        fig, label = FIGURES[r.name]
        y = np.where(stable, figs[fig], np.nan)
        out.append(rank(r.name, label, r.unit, keys, X, y, inert=inert_linear, log_keys=_log_keys(tol),
                        confidence=tol.confidence, sobol_run=margin_sobol(r.name)))
    if runs is not None:
        inert_time = np.array([k in runs.rows.inert for k in keys])
        shown = {"tracking_error": (runs.tracking_error, "tracking error"), "peak_current": (runs.peak_current,
                                                                                           "peak current")}
        units = {r.name: r.unit for r in timed}
        for name, (y, label) in shown.items():
            unit = "A" if name == "peak_current" else ("mm" if scene.drivetrain.output_is_linear else "deg")
            out.append(rank(name, label, units.get(name, unit), keys, X, y,
                            inert=inert_time, log_keys=_log_keys(tol), confidence=tol.confidence,
                            sobol_run=None if not sobol_runs else _time_sobol(tol, scene, runs, name, sobol_runs,
                                                                              cache, seed, executor)))
    return tuple(out)


def _time_sobol(tol, scene, runs, name, base, cache, seed, executor=None):
    """Sobol indices of a time figure from ``base (d + 2)`` further time runs (one set of
    runs gives both time figures: ``cache`` keeps it for the second), in chunks on
    ``executor`` as the study's other time runs (the figures do not depend on it)."""
    from .tolerance_runs import tolerance_runs

    def run(live):
        live_keys = [k for k, m in zip(tol.keys, live) if m]
        key = ("time", tuple(live_keys))
        if key not in cache:
            def func(x):
                vals = {k: np.full(x.shape[1], tol.item(k).nominal) for k in tol.keys}
                vals.update({k: x[j] for j, k in enumerate(live_keys)})
                r = tolerance_runs(scene, vals, runs.rows.controller, keys=runs.rows.keys, progress=False,
                                   duration=runs.duration_s, dt=runs.dt_s, executor=executor)
                return np.array([np.where(r.failed, np.nanmax(y), y) for y in (r.tracking_error, r.peak_current)])
            cache[key] = sobol(func, [tol.item(k) for k in live_keys], base, seed=seed, confidence=tol.confidence)
        j = 0 if name == "tracking_error" else 1
        return {k: v[j:j + 1] if isinstance(v, np.ndarray) else v for k, v in cache[key].items()}
    return run


def _score(margins, figs, timed=(), shown=None, undecided=None):
    """Per variant: its smallest relative margin to a requirement (each shortfall divided by
    its limit) and which requirement (an index into ``margins + timed``); -inf for an unstable
    loop or a time run failed by its physics (its figures NaN in ``shown``); a time run
    without a verdict (``undecided``) is judged on the other requirements."""
    rows = [_relative_margin(r, figs[FIGURES[r.name][0]]) for r in margins]
    if timed:
        rows += [np.where(undecided, np.inf, _relative_margin(r, shown[r.name])) if undecided is not None
                 else _relative_margin(r, shown[r.name]) for r in timed]
    rel = np.array(rows) if rows else np.zeros((1, figs["stable"].size))
    rel = np.where(np.isnan(rel), -np.inf, rel)
    k = np.argmin(rel, axis=0)
    score = rel[k, np.arange(rel.shape[1])]
    return np.where(figs["stable"], score, -np.inf), k


def _worst_corner(scene, tol, values, figs, margins, plants, p, ctrl, f_req, keys, zeta, runs, duration, timed=(),
                  executor=None, seed=0):
    """The corner that fails worst, built exactly and run again: the smallest relative margin
    to a requirement over the linear figures and, when the study judges time requirements
    (``timed``), over the corners' time runs too (each requirement's shortfall divided by its
    limit)."""
    from ..loop.robustness import variant_figures
    timed = list(timed)
    inert = set(plants.inert) & (set(runs.rows.inert) if timed else set(plants.inert))
    live = [t for t in tol.items if t.key not in inert]
    nominal = {t.key: t.nominal for t in tol.items}
    if not live:
        return None
    if 2 ** len(live) <= MAX_CORNERS and plants.mapper is not None:
        combos = np.array(list(itertools.product(*[t.ends for t in live])), float)
        how = len(combos)
    else:
        score, _ = _score(margins, figs, timed, _time_shown(scene, runs) if timed else None)
        finite = np.isfinite(score)
        fill = np.where(finite, score, np.min(score[finite]) - 1.0 if finite.any() else -1.0)
        X = np.column_stack([values[t.key] for t in live])
        coef = np.linalg.lstsq(np.column_stack([np.ones(len(X)), X]), fill, rcond=None)[0][1:]
        combos = np.array([[t.ends[0] if c > 0 else t.ends[1] for t, c in zip(live, coef)]])
        how = 1
    vals = {k: np.full(len(combos), v) for k, v in nominal.items()}
    vals.update({t.key: combos[:, j] for j, t in enumerate(live)})
    cp = plants.mapper(vals) if plants.mapper is not None else None
    cf = variant_figures(scene, p, ctrl, vals, f_req, plants=cp, progress=False, structural_damping=zeta)
    shown, undecided, reasons, notes = None, None, None, []
    if timed:
        from .tolerance_runs import tolerance_runs
        cr = tolerance_runs(scene, vals, ctrl, keys=keys, executor=executor, progress=False, duration=runs.duration_s,
                            dt=runs.dt_s, seed=seed)
        physical = _physical(cr, cf["stable"])
        undecided, reasons = cr.failed & ~physical, cr.reasons
        shown = {k: np.where(physical, np.nan, v) for k, v in _time_shown(scene, cr).items()}
        if undecided.any():
            j = int(np.flatnonzero(undecided)[0])
            notes.append(f"{int(undecided.sum())} of {how} corners could not run in time (first: {reasons[j]}): "
                         f"judged on their margins only")
    score, which = _score(margins, cf, timed, shown, undecided)
    unstable = ~np.asarray(cf["stable"], bool)
    i = int(np.argmax(np.where(unstable, cf["max_pole_real"], -np.inf)) if unstable.any() else np.argmin(score))
    corner = {k: float(v[i]) for k, v in vals.items()}
    figures = {k: float(v[i]) for k, v in cf.items()}
    reference = _corner_margins(keys, corner, p, ctrl, scene, zeta)
    simulation, failed = _corner_run(scene, keys, corner, ctrl, runs, duration)
    names = [r.name for r in margins + timed]
    figure = names[int(which[i])] if names and not unstable[i] else "stable"
    time_figures = {} if shown is None else {r.name: float(shown[r.name][i]) for r in timed}
    if reasons is not None and reasons[i] and not undecided[i]:
        time_figures["failed"] = reasons[i]
    basis = "every requirement (margins and time runs)" if timed else "the linear figures"
    return WorstCorner(corner, float(score[i]), figure, how, figures, reference, simulation, failed, basis,
                       time_figures, tuple(notes), {t.key: t.unit for t in tol.items})


def _split(corner):
    from ..scene.tolerances import STIFFNESS_SCALE
    return {k: v for k, v in corner.items() if k != STIFFNESS_SCALE}, corner.get(STIFFNESS_SCALE, 1.0)


def _corner_margins(keys, corner, p, ctrl, scene, zeta) -> dict:
    """python-control's margins of the corner's plant, built exactly (the slow, independent
    path)."""
    import control as ct

    from ..loop.closed_loop import open_loop_of
    from ..plant.linear import PLANT_OUTPUTS, plant_matrices, plant_parameters
    from dataclasses import replace
    values, scale = _split(corner)
    q = plant_parameters(keys.scene(values), p.q0, "rigid" if p.rigid else "two_mass", zeta)
    if not p.rigid:
        from ..plant.linear import spring_damping
        q = replace(q, K=q.K * scale, c=float(spring_damping(q.J1, q.J2, q.K * scale, zeta)))
    A, B, C, D, states = plant_matrices(q)
    g = ct.ss(A, B, C, D, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states)
    loop = open_loop_of(g, ctrl, scene.motor)
    gm, pm, *_ = ct.stability_margins(loop)
    return {"gain_margin_db": float(20 * np.log10(gm)) if gm and np.isfinite(gm) else math.inf,
            "phase_margin_deg": float(pm) if np.isfinite(pm) else math.inf}


def _corner_run(scene, keys, corner, ctrl, runs, duration):
    """The corner's nonlinear closed loop: simulate's command on the same model."""
    from dataclasses import replace

    from ..sim import simulate
    from ..sim.tolerance_rows import keep_effects
    from .time_reference import run_spec
    from .time_run import sine_run_options
    values, scale = _split(corner)
    cs = keys.scene(values)
    reference, run_duration, *_ = run_spec(cs, None)
    options, _ = sine_run_options(scene, ctrl, reference)
    options, _ = keep_effects(options, corner)
    options = replace(options, stiffness_scale=options.stiffness_scale * scale)
    try:
        return simulate(cs, ctrl, reference=reference, duration=duration or run_duration, method="rk4",
                        dt=None if runs is None else runs.dt_s, options=options), ""
    except (SimulationError, SceneError) as exc:
        return None, str(exc)


__all__ = ["FIGURES", "sampling_notes", "tolerance_study"]
