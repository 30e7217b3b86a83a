"""The tolerance study: what fraction of built actuators meets the requirements, and which
tolerance to tighten.

Variants are drawn from the scene's ``[tolerances]`` (:mod:`servo_toolkit.scene.tolerances`;
a ``[robustness]`` table's ranges count as tolerances) by Latin hypercube, scrambled Sobol or
independent draws (:func:`servo_toolkit.loop.sampling.sample_tolerances`). Each variant's
linear loop with the designed controller gives its margins
(:func:`servo_toolkit.loop.robustness.variant_figures` on plants mapped from the keys,
:mod:`servo_toolkit.loop.variant_plants`); where the scene bounds the tracking error or the
peak current, each variant also runs in time on the nonlinear model
(:mod:`.time_runs`). Then:

- the *yield* of every requirement, and of all of them at once, with its Clopper-Pearson
  interval (:mod:`servo_toolkit.core.yields`); ``min_yield`` is met when the interval's lower
  end reaches it;
- the *sensitivity* of each figure to each tolerance (:mod:`servo_toolkit.core.sensitivity`:
  standardized regression where the figure is near-linear, Sobol indices where not, a key
  that does not enter the figure exactly 0);
- the *worst corner*: every corner of the tolerance box (each tolerance at an end; up to
  2^10, on the variants' maps or built exactly as they were) through the linear study and, when the scene bounds a time figure, through batched time runs too;
  the one with the smallest margin to a requirement (each shortfall divided by its limit,
  over every requirement judged) built exactly, its margins checked with python-control's arithmetic and
  its nonlinear closed loop run on its own.
"""

from __future__ import annotations

import numpy as np

from ...errors import SceneError, SimulationError
from ...core.sensitivity import rank, sobol
from ...core.yields import Yield
from ...plant.linear import DEFAULT_STRUCTURAL_DAMPING
from .figures import FIGURES, meets as _meets, physical_failures as _physical, time_shown as _time_shown
from .result import ToleranceResult

#: base sample of the Sobol indices of a nonlinear margin figure (n (d + 2) evaluations)
SOBOL_BASE = 512


def _requirements(scene, result, tol):
    """(margin requirements, time requirements) in display units."""
    from ...loop.requirements import robust_requirements, time_requirements
    from ...scene.loader import Robustness
    spec = scene.robustness or Robustness(load_inertia=None, stiffness=None)
    margins = [r for r in robust_requirements(spec, result.requirements) if r.name != "stable_fraction"]
    return margins, time_requirements(scene, tol, "tolerances")


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
    from ...loop.robustness import variant_figures
    from ...loop.sampling import sample_tolerances
    from ...loop.variant_plants import keyed_plants
    from ...scene.tolerances import check_ends
    from ..run import has_motor_drivetrain
    tol = scene.tolerances
    if tol is None:
        raise SceneError("tolerances", "the scene sets no [tolerances] (nor [robustness] ranges) to vary")
    if not has_motor_drivetrain(scene):
        raise SceneError("tolerances", "a tolerance study needs a motor-driven drivetrain ([motor] and [[drivetrain]])")
    check_ends(tol)
    if result is None:
        from ...loop import design
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
        from .time_runs import tolerance_runs
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
        from .corner import worst_corner as find_worst
        worst = find_worst(scene, tol, values, figs, margins, plants, p, ctrl, f_req, keys, structural_damping,
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


def _variances(tol):
    """Each tolerance's population variance as the regression sees it (of its logarithm
    for a log-uniform one): the shares' V_k (:mod:`servo_toolkit.core.sensitivity`)."""
    return np.array([t.variance(log) for t, log in zip(tol.items, _log_keys(tol))])


def _sensitivities(tol, values, figs, margins, runs, timed, plants, scene, p, ctrl, f_req, zeta, sobol_runs, seed,
                   executor=None):
    """Ranking of the tolerances on each requirement's figure."""
    from ...loop.robustness import variant_figures
    keys = tol.keys
    X = np.column_stack([values[k] for k in keys])
    inert_linear = np.array([k in plants.inert for k in keys])
    variances = _variances(tol)
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
                        confidence=tol.confidence, sobol_run=margin_sobol(r.name), variances=variances, seed=seed))
    if runs is not None:
        inert_time = np.array([k in runs.rows.inert for k in keys])
        shown = {"tracking_error": (runs.tracking_error, "tracking error"), "peak_current": (runs.peak_current,
                                                                                           "peak current")}
        units = {r.name: r.unit for r in timed}
        for name, (y, label) in shown.items():
            unit = "A" if name == "peak_current" else ("mm" if scene.drivetrain.output_is_linear else "deg")
            out.append(rank(name, label, units.get(name, unit), keys, X, y,
                            inert=inert_time, log_keys=_log_keys(tol), confidence=tol.confidence,
                            variances=variances, seed=seed,
                            sobol_run=None if not sobol_runs else _time_sobol(tol, scene, runs, name, sobol_runs,
                                                                              cache, seed, executor)))
    return tuple(out)


def _time_sobol(tol, scene, runs, name, base, cache, seed, executor=None):
    """Sobol indices of a time figure from ``base (d + 2)`` further time runs (one set of
    runs gives both time figures: ``cache`` keeps it for the second), in chunks on
    ``executor`` as the study's other time runs (the figures do not depend on it)."""
    from .time_runs import tolerance_runs

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


__all__ = ["FIGURES", "sampling_notes", "tolerance_study"]
