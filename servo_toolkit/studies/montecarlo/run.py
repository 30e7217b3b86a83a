"""Nonlinear Monte Carlo: the closed-loop time run of many parameter variants at once.

The time-domain counterpart of :func:`servo_toolkit.loop.robustness.robustness`: the same
variation names, ranges and sampling (``check --vary``, a scene's ``[robustness]``), the
same command as ``servo-toolkit simulate`` (the 8 Hz, 2 deg sine for 1 s; 1 mm for an
output travel) and the same reduced or full model. Every variant runs the designed
controller on the nonlinear model (saturation, friction, backlash, sampling, quantization)
through the batched kernel (:mod:`servo_toolkit.sim.batch`), and is step-checked at its
own parameters (the RK4 stability region at its start, peak current, largest drivetrain
deflection and end, each also in contact and at a speed reversal: :mod:`.variant_step`). Chunks of variants go to an optional executor (a process pool, a dask
``Client.get_executor()``).

A variant's parameter row comes from :class:`~servo_toolkit.sim.variants.VariantBuilder`'s
linear map of the drivetrain slots when that map is exact (checked against
:func:`~servo_toolkit.sim.model.build_model` at the farthest variant); otherwise (a chain whose
two-mass reduction moves nonlinearly with the load inertia, the full chain) from
:class:`~servo_toolkit.sim.tolerance_rows.ToleranceRows`' separable fit over the keys
``load.inertia`` and ``drivetrain.stiffness_scale``, verified against exact models; every
variant is built with ``build_model`` only when that fit does not verify.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...errors import SceneError, SimulationError
from ...loop.robustness import default_variations, sample_variants
from ...scene.loader import scene_keys
from ...scene.tolerances import STIFFNESS_SCALE
from ...core.parallel import chunks, run_cases
from ...sim import controller_for
from ...sim.simulate import with_feedforward
from ...sim import layout as lo
from ...sim.batch import F_CUR, F_ERR, F_SAT, F_STATUS, F_STEP
from ...sim.batch_run import integrate_variants
from ...sim.reference import fill, initial_state
from ...sim.tables import frozen_tables
from ...sim.variants import VariantBuilder, with_load_inertia
from ...sim.tolerance_rows import ToleranceRows
from ..time.reference import run_spec
from ..batch_step import batch_step
from ..time.run import check_friction, lumped_if_reshaped_at, sine_run_options
from .result import MonteCarloResult
from .variant_step import step_check

#: variants per chunk (each chunk runs in parallel across the cores of its worker)
CHUNK_SIZE = 2000
#: variants per chunk at most when every variant carries its own stroke tables (fitted rows)
TABLE_CHUNK_SIZE = 500
#: exact models along each varied key for the fitted rows: a reduction's stiffness and split
#: move steeply near zero load (over the inertia the drivetrain keeps on its load side); the
#: stiffness factor moves the rows smoothly (on the reference EMA nine points verify as well as
#: 41: 5.4e-6, the load inertia's share)
ROW_POINTS = {"load_inertia": 41, "stiffness": 9}
#: exact models a fit needs besides its grids: the nominal one (the model's and the fit's), the
#: fit's four checks and the four corners of the sampled box, two more variants verifying the rows
FIT_OVERHEAD = 12
#: the Monte Carlo's variations -> the scene keys the fitted rows vary
KEYS = {"load_inertia": "load.inertia", "stiffness": STIFFNESS_SCALE}


def _chunk(case):
    """Run one chunk of variants (module level: picklable for process pools and dask)."""
    rows = case.get("rows")
    if rows is not None:  # fitted rows: mapped from the chunk's key values here (in the worker)
        P, T, tix = rows.rows(case["X"])
        moved = {"deltas": np.zeros(len(P)), "d_table": None} if T.shape[0] == 1 and not np.any(tix) else {"T": T[tix]}
        case = dict(case, model=rows.model, P=P, **moved)
    model, P, dt, n_steps, sub = case["model"], case["P"], case["dt"], case["n_steps"], case["sub"]
    T = case.get("T")
    if T is None:
        deltas, d_table = case["deltas"], case["d_table"]
        if d_table is None or not np.any(deltas):
            T, tix = model.T[None], np.zeros(len(P), dtype=np.int64)
        else:
            T = model.T[None] + deltas[:, None, None] * d_table[None]
            tix = np.arange(len(P))
    else:
        tix = np.arange(len(P))
    T = frozen_tables(T)  # as a single run's: the same kernels serve the variants
    models = [model] * len(P) if case.get("T") is None else [replace(model, T=t) for t in T]
    X0, refused = _starts(models, P)
    _, figs, snaps, wall = integrate_variants(P, T, tix, X0, dt, n_steps, sub)
    lam_dt, stable = step_check(model, P, T, tix, X0, snaps, dt)
    none = np.array([bool(r) for r in refused], dtype=bool)
    figs[none, F_ERR] = figs[none, F_CUR] = np.nan  # never run: no figures
    return {"figs": figs, "lam_dt": lam_dt, "stable": stable, "wall": wall, "refused": refused}


def _starts(models, P):
    """Each variant's start (:func:`~servo_toolkit.sim.reference.initial_state`) and, per
    variant, why it has none ("" where it has one): a variant whose compliances cannot carry
    the load within the stroke tables is a failed variant with that reason, not the end of
    the study. Its start is NaN, so its run stops at once."""
    X0 = np.full((len(P), models[0].nx if models else 0), np.nan)
    refused = [""] * len(P)
    for i, (m, p) in enumerate(zip(models, P)):
        try:
            X0[i] = initial_state(m, p)
        except SimulationError as exc:
            refused[i] = f"no start: {exc}"
    return X0, refused


def joined(parts, dt):
    """The chunks' results ``parts`` of :func:`_chunk` as one: ``(figs, lam_dt, stable,
    reasons, failed)``, each variant's reason for failing ("" if it did not: its start
    refused, else :func:`_reason`) and whether it failed (it has a reason)."""
    figs = np.concatenate([p["figs"] for p in parts])
    lam_dt = np.concatenate([p["lam_dt"] for p in parts])
    stable = np.concatenate([p["stable"] for p in parts])
    refused = [r for p in parts for r in p["refused"]]
    status = figs[:, F_STATUS].astype(int)
    reasons = tuple(no or _reason(s, st, dt, ok, ld) for no, s, st, ok, ld in
                    zip(refused, status, figs[:, F_STEP], stable, lam_dt))
    return figs, lam_dt, stable, reasons, np.array([bool(r) for r in reasons], dtype=bool)


def _reason(status, step, dt, stable, lam_dt):
    """Why a variant failed ("" if it did not); an unstable step is named first, since it
    also explains a non-finite state or a run off the stroke."""
    stop = ("" if status == lo.OK else
            f"non-finite state at t = {step * dt:.6g} s" if status == lo.NONFINITE else
            f"stroke end reached at t = {step * dt:.6g} s")
    if not stable:
        return (f"step {dt:.4g} s outside the RK4 stability region at this variant's parameters "
                f"(|lambda dt| up to {lam_dt:.3g})" + (f"; {stop}" if stop else ""))
    return stop


def unvaried_tolerances(scene, values) -> list:
    """Notes on the scene's ``[tolerances]`` keys against this run: the keys it leaves at
    their values (the Monte Carlo varies ``load_inertia``, which is ``load.inertia``, and
    ``stiffness``, which is ``drivetrain.stiffness_scale``; ``tolerance_study`` with
    ``nonlinear=True`` runs every tolerance in time), and a key it varies over its own
    range rather than the tolerance's."""
    from ...loop.vary import ranges_text
    tol = scene.tolerances
    if tol is None:
        return []
    covered = {"load.inertia": "load_inertia", STIFFNESS_SCALE: "stiffness"}
    left = [k for k in tol.keys if covered.get(k) not in values]
    notes = []
    if left:
        notes.append(f"the scene's [tolerances] {', '.join(left)} are not varied here (this Monte Carlo varies "
                     f"{', '.join(values)}): servo-toolkit tolerances --nonlinear runs every tolerance in time")
    given = scene.robustness.ranges if scene.robustness is not None else {}
    for t in tol.items:
        name = covered.get(t.key)
        if name not in values or name in given:  # [robustness]'s range is the tolerance itself
            continue
        run = (float(np.min(values[name])), float(np.max(values[name])))
        if not np.allclose(run, (t.low, t.high), rtol=1e-9, atol=0.0):
            shown = {name: np.array(run)}, {name: np.array([t.low, t.high])}
            linear = scene.drivetrain.output_is_linear
            notes.append(f"the scene's [tolerances] {t.key} is varied over this run's range "
                         f"({ranges_text(shown[0], scene.display, linear)}), not over its tolerance "
                         f"({ranges_text(shown[1], scene.display, linear)}): servo-toolkit tolerances "
                         f"--nonlinear draws it as the scene states")
    return notes


def montecarlo(scene, variants=None, *, samples: int | None = None, seed: int | None = None,
               grid: bool | None = None, duration: float | None = None, full: bool = False,
               controller=None, reference=None, dt: float | None = None, executor=None,
               chunk_size: int = CHUNK_SIZE, progress: bool = True, feedforward=None,
               friction: str | None = None) -> MonteCarloResult:
    """Closed-loop time runs of parameter variants of ``scene``, batched.

    Parameters
    ----------
    scene : Scene
    variants : dict, optional
        name -> (lo, hi) range or array of values (``load_inertia`` in kg*m^2 replacing the
        load's, ``stiffness`` a factor on the series stiffness). Default: the scene's
        ``[robustness]`` ranges, else load inertia 0 .. 4 times the scene's and stiffness
        0.7..1.3 (:func:`~servo_toolkit.loop.robustness.default_variations`).
    samples, seed, grid : optional
        Sampling of ranges as :func:`~servo_toolkit.loop.robustness.sample_variants`
        (default: the scene's ``[robustness]``, else 1000 Monte Carlo draws, seed 0).
    duration : float, optional
        Seconds (default: ``simulate``'s, 1 s).
    full : bool
        Run the full model (default: the reduced model ``simulate`` runs for the command).
    controller : CascadeController, optional
        Default: the scene's design (:func:`servo_toolkit.sim.controller_for`), the same
        controller on every variant.
    reference : Reference, optional
        Default: ``simulate``'s command (8 Hz, 2 deg sine; 1 mm for an output travel).
    dt : float, optional
        Fixed step (s); default the one ``simulate`` chooses for the nominal model, checked
        along a run of the nominal model and reduced as a single run's automatic step is
        (:func:`~.batch_step.batch_step`; a given step outside the region there is refused).
        Each variant is checked against the RK4 stability region at its own parameters.
    executor : concurrent.futures.Executor, optional
        Runs chunks of ``chunk_size`` variants.
    chunk_size : int
    progress : bool
    feedforward : Feedforward or {"off", "gains", "model"}, optional
        Replaces the controller's feedforward. A model-based feedforward keeps the nominal
        scene's load inertia in every variant (``Feedforward.load_inertia``, unless it sets
        its own), as a drive's does: it does not know a variant's true inertia.
    friction : {"stick", "smooth", "off"}, optional
        The friction model (``ModelOptions.friction``; None: simulate's, smooth). Friction
        that holds runs in the batch as in the single run (the same loop: a variant's step
        split at its speed reversals and breakaways).

    Returns
    -------
    MonteCarloResult

    Raises
    ------
    SceneError
        Unknown variation, bad range, a variant without load-side inertia, a duration or
        step that is not positive, a given step outside the stability region along the
        nominal run.
    """
    if friction is not None:
        check_friction(friction)  # before any work
    spec = scene.robustness
    if variants is None:
        variants = spec.ranges if spec is not None else default_variations(scene)
    samples = samples if samples is not None else (spec.samples if spec is not None else 1000)
    seed = seed if seed is not None else (spec.seed if spec is not None else 0)
    grid = grid if grid is not None else (spec is not None and spec.method == "grid")
    if samples < 1:
        raise SceneError("samples", f"must be at least 1 (got {samples})")
    values = sample_variants(variants, samples, grid, seed)
    ref, run_duration, _, _, _ = run_spec(scene, None)
    reference = reference or ref
    duration = run_duration if duration is None else float(duration)
    if not duration > 0:
        raise SceneError("duration", f"must be positive (got {duration:g} s)")
    source = "controller given by the caller"
    if controller is None:
        controller, source = controller_for(scene)
        source = f"controller from {source}"
    controller = nominal_feedforward(with_feedforward(controller, feedforward, scene), scene)
    options, notes = sine_run_options(scene, controller, reference, full, friction=friction,
                                      stiffness=_factors(values.get("stiffness")))
    options, notes = lumped_if_reshaped(scene, controller, options, notes, values)
    notes.insert(0, f"{source}, the same on every variant")
    notes += unvaried_tolerances(scene, values)
    builder = VariantBuilder.create(scene, controller, options, varied=tuple(values))
    if builder.fast and not builder.self_check(values):
        builder = replace(builder, fast=False)
    model = builder.model
    if "stiffness" in values and model.rigid:
        notes.append("the drivetrain is rigid (no stage has a stiffness): the stiffness factor acts on nothing, "
                     "every stiffness gives the same figures")
    P0 = fill(model, reference)
    rows = None
    if not builder.fast:
        rows, note = fitted_rows(scene, builder, P0, values, reference)
        notes.append(note)
    dt, step_note = batch_step(model, P0, initial_state(model, P0), duration, dt)
    notes.append(step_note)
    n_steps = max(1, int(round(duration / dt)))
    sub = int(round(model.sample_time / dt)) if P0[lo.CMODE] == lo.SAMPLED else 0
    cases = _cases(builder, P0, values, reference, dt, n_steps, sub, chunk_size, rows)
    parts = run_cases(_chunk, cases, executor=executor, progress=progress, description="montecarlo")
    figs, lam_dt, _, reasons, failed = joined(parts, dt)
    linear = bool(scene.drivetrain.output_is_linear)
    return MonteCarloResult(
        scene_name=scene.name, values=values, tracking_error=figs[:, F_ERR], peak_current=figs[:, F_CUR],
        saturated=figs[:, F_SAT] > 0, failed=failed, reasons=reasons, abs_lambda_dt=lam_dt,
        wall_s=float(sum(p["wall"] for p in parts)), dt_s=float(dt), steps_per_variant=n_steps,
        duration_s=duration, linear_output=linear, display=scene.display,
        settings={"samples": int(samples), "seed": int(seed), "method": "grid" if grid else "monte_carlo",
                  "model": "full" if full else "reduced", "reference": reference.to_dict(),
                  "controller": model.controller,
                  "feedforward": None if controller.feedforward is None else controller.feedforward.to_dict()},
        notes=(*notes, *model.notes), runner=(builder, P0, reference, rows))


def lumped_if_reshaped(scene, controller, options, notes, values):
    """``(options, notes)`` with the chain's modes lumped again when they were kept for a
    varied stiffness but the full chain changes form within the load range (a load node
    without inertia at a load inertia of 0: ``--full`` refuses such a range); the note then
    says that the softest variants carry the lumping's cost. Unchanged otherwise."""
    if "load_inertia" not in values:
        return options, notes
    low = float(np.min(values["load_inertia"]))
    return lumped_if_reshaped_at(scene, controller, options, notes,
                                 {f"load_inertia = {low:.4g}": with_load_inertia(scene, low)}, "a node without inertia")


def _factors(stiffness):
    """(smallest, largest) of the stiffness factors a run varies, None when it varies none."""
    return None if stiffness is None else (float(np.min(stiffness)), float(np.max(stiffness)))


def fitted_rows(scene, builder, P0, values, reference):
    """The variants' rows fitted by :class:`~servo_toolkit.sim.tolerance_rows.ToleranceRows`
    (None when they cannot be verified: every variant is then built with ``build_model``),
    and the note saying how the rows are made.

    The load inertia's points are graded over the inertia the drivetrain keeps on its load
    side at zero load (where the two-mass reduction's stiffness and split move steeply). The
    fit's nominal row must equal ``P0``: a scene changed after it was read from its file is
    built exactly, and so are fewer variants than the fit would build exact models.
    """
    one_by_one = "variants built one by one with build_model (their parameters move beyond the drivetrain slots"
    inner = float(builder.model.P[lo.JL]) - builder.d_jl * float(scene.load.inertia)
    grade = {KEYS["load_inertia"]: inner} if builder.d_jl > 0 and inner > 0 else {}
    if not set(values) <= set(KEYS):
        return None, f"{one_by_one})"
    n = next(iter(values.values())).size
    points = tuple(ROW_POINTS[k] for k in values)
    if n <= sum(points) + FIT_OVERHEAD:
        return None, f"{one_by_one}; fewer than a fit's exact models)"
    try:
        keyed = {KEYS[k]: np.asarray(v, float) for k, v in values.items()}
        rows = ToleranceRows.create(scene, scene_keys(scene), keyed, builder.controller, builder.options, reference,
                                    points=(points,), grade=grade)
    except SceneError as exc:
        return None, f"{one_by_one}; fitted rows not available: {exc})"
    if rows.P0.shape != P0.shape or not np.array_equal(rows.P0, P0, equal_nan=True):
        return None, f"{one_by_one}; the scene differs from its file)"
    if rows.fitted is None:
        return None, f"{one_by_one}; the fitted rows verified only to a relative {rows.error:.2g})"
    return rows, (f"variant rows fitted from {rows.evaluations} exact models, verified to a relative "
                  f"{rows.error:.2g} (the linear map of the drivetrain slots is not exact here)")


def nominal_feedforward(controller, scene):
    """The controller with a model-based feedforward pinned to ``scene``'s load inertia (the
    nominal model a drive's feedforward is built from); unchanged otherwise."""
    ff = controller.feedforward
    if ff is None or not ff.model or ff.load_inertia is not None:
        return controller
    return replace(controller, feedforward=replace(ff, load_inertia=float(scene.load.inertia)))


def _cases(builder, P0, values, reference, dt, n_steps, sub, chunk_size, rows=None):
    """Chunks of variant rows (picklable dicts); with fitted ``rows``, the chunk's variants'
    key values (mapped to rows in the chunk)."""
    n = next(iter(values.values())).size
    common = {"model": builder.model, "dt": dt, "n_steps": n_steps, "sub": sub}
    if rows is not None:
        X = np.column_stack([values[k] for k in values])  # KEYS keep the order: rows.names
        size = min(int(chunk_size), TABLE_CHUNK_SIZE) if rows.table_moves else int(chunk_size)
        mapper = replace(rows, keys=None, controller=None, reference=None)  # what rows() reads: picklable
        return [dict(common, rows=mapper, X=X[idx]) for idx in chunks(np.arange(n), max(1, size))]
    out = []
    for idx in chunks(np.arange(n), max(1, int(chunk_size))):
        part = {k: v[idx] for k, v in values.items()}
        if builder.fast:
            P = np.empty((idx.size, P0.size))
            deltas = np.zeros(idx.size)
            for r, i in enumerate(idx):
                P[r], dT = builder.row(P0, part["load_inertia"][r] if "load_inertia" in part else None,
                                       part["stiffness"][r] if "stiffness" in part else None)
                if "load_inertia" in part:
                    deltas[r] = part["load_inertia"][r] - builder.scene.load.inertia
            out.append(dict(common, P=P, deltas=deltas, d_table=builder.d_table))
        else:
            P, T, _ = builder.rows(P0, part, lambda m: fill(m, reference))
            out.append(dict(common, P=P, T=T))
    return out
