"""The worst corner of a tolerance study: every corner of the tolerance box (each tolerance
at an end: a range's ends, a normal's mean +- 3 sigma; up to :data:`MAX_CORNERS`, on the
variants' plant maps or, where those did not verify, built exactly as the variants were;
beyond, the one corner the regression's signs point to) through the linear study and, when
the study judges time requirements, through batched time runs too
(:func:`~.time_runs.tolerance_runs`); the corner that misses a requirement by the most
(each shortfall divided by its limit) is built exactly, its margins checked with
python-control's arithmetic on a state-space loop and its nonlinear closed loop run on its own (``simulate``'s command)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from ...errors import SceneError, SimulationError
from .result import MAX_CORNERS, WorstCorner
from .figures import FIGURES, physical_failures as _physical, relative_margin as _relative_margin, \
    time_shown as _time_shown

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


def worst_corner(scene, tol, values, figs, margins, plants, p, ctrl, f_req, keys, zeta, runs, duration, timed=(),
                  executor=None, seed=0):
    """The corner that fails worst, built exactly and run again: the smallest relative margin
    to a requirement over the linear figures and, when the study judges time requirements
    (``timed``), over the corners' time runs too (each requirement's shortfall divided by its
    limit)."""
    from ...loop.robustness import variant_figures
    from ...loop.variant_plants import keyed_plants
    timed = list(timed)
    inert = set(plants.inert) & (set(runs.rows.inert) if timed else set(plants.inert))
    live = [t for t in tol.items if t.key not in inert]
    nominal = {t.key: t.nominal for t in tol.items}
    if not live:
        return None
    if 2 ** len(live) <= MAX_CORNERS:
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
    # the variants' maps where they verified, else every corner built exactly as the variants were
    cp = plants.mapper(vals) if plants.mapper is not None else keyed_plants(scene, p, vals, zeta, keys=keys, exact=True)
    cf = variant_figures(scene, p, ctrl, vals, f_req, plants=cp, progress=False, structural_damping=zeta)
    shown, undecided, reasons, notes = None, None, None, []
    if plants.mapper is None:
        notes.append(f"the worst corner's search built its {how} corner{'s' if how > 1 else ''} exactly, "
                     f"as the variants were")
    if timed:
        from .time_runs import tolerance_runs
        cr = tolerance_runs(scene, vals, ctrl, keys=keys, executor=executor, progress=False, duration=runs.duration_s,
                            dt=runs.dt_s, seed=seed, spans=runs.spans)
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
                       time_figures, tuple(notes), {t.key: t.unit for t in tol.items}, 2 ** len(live))


def _split(corner):
    from ...scene.tolerances import STIFFNESS_SCALE
    return {k: v for k, v in corner.items() if k != STIFFNESS_SCALE}, corner.get(STIFFNESS_SCALE, 1.0)


def _corner_margins(keys, corner, p, ctrl, scene, zeta) -> dict:
    """The margins of the corner's plant, built exactly as a state-space loop (the slow,
    independent path; python-control's ``stability_margins`` arithmetic,
    :func:`servo_toolkit.lti.analysis.stability_margins`)."""
    from ...lti.analysis import stability_margins
    from ...lti.system import ss
    from ...loop.closed_loop import open_loop_block_of
    from ...plant.linear import PLANT_OUTPUTS, plant_matrices, plant_parameters
    from dataclasses import replace
    values, scale = _split(corner)
    q = plant_parameters(keys.scene(values), p.q0, "rigid" if p.rigid else "two_mass", zeta)
    if not p.rigid:
        from ...plant.linear import spring_damping
        q = replace(q, K=q.K * scale, c=float(spring_damping(q.J1, q.J2, q.K * scale, zeta)))
    A, B, C, D, states = plant_matrices(q)
    g = ss(A, B, C, D, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states)
    gm, pm, *_ = stability_margins(open_loop_block_of(g, ctrl, scene.motor))
    return {"gain_margin_db": float(20 * np.log10(gm)) if gm and np.isfinite(gm) else math.inf,
            "phase_margin_deg": float(pm) if np.isfinite(pm) else math.inf}


def _corner_run(scene, keys, corner, ctrl, runs, duration):
    """The corner's nonlinear closed loop: simulate's command on the same model, over the
    batch runs' duration (the model itself, as the batch runs it: no whole-period rule)."""
    from dataclasses import replace

    from ...sim import build_model, run
    from ...sim.tolerance_rows import keep_effects
    from ..time.reference import run_spec
    from ..time.run import sine_run_options
    from .time_runs import stiffness_factors
    values, scale = _split(corner)
    cs = keys.scene(values)
    reference, run_duration, *_ = run_spec(cs, None)
    if runs is not None:  # the variants' model
        options = runs.rows.options
    else:
        options, _ = sine_run_options(scene, ctrl, reference,
                                      stiffness=stiffness_factors(scene, keys, {k: [v] for k, v in corner.items()}))
    options, _ = keep_effects(options, corner)
    options = replace(options, stiffness_scale=options.stiffness_scale * scale)
    try:
        return run(build_model(cs, ctrl, options), reference, duration or run_duration, "rk4",
                   None if runs is None else runs.dt_s), ""
    except (SimulationError, SceneError) as exc:
        return None, str(exc)


__all__ = ["MAX_CORNERS", "worst_corner"]
