"""Nonlinear closed-loop time runs of tolerance variants, batched.

The time-domain half of the tolerance study (:mod:`.run`): every variant of a
scene's ``[tolerances]`` (any scene keys) runs the designed controller on the nonlinear model
(saturation, friction, backlash, sampling, quantization), through the batched kernel as
:func:`~.montecarlo.run.montecarlo` runs its variants, with the same command as ``servo-toolkit
simulate`` (the 8 Hz, 2 deg sine for 1 s; 1 mm for an output travel) on the same reduced
model, every toleranced effect kept in it (:func:`~servo_toolkit.sim.tolerance_rows.keep_effects`).
A tolerance on the drivetrain's stiffness (``drivetrain.stiffness_scale``, a stage's stiffness
key) gives the reduction the range of factors on the series stiffness it spans
(:func:`stiffness_factors`), as a Monte Carlo over the stiffness does: the compliance is kept,
and so are the chain's modes above the first when lumping them costs too much at the softest
variant (:func:`~servo_toolkit.studies.reduce.estimates.varied_stiffness`).
Each variant's parameter row (and its stroke tables where they move) comes from
:class:`~servo_toolkit.sim.tolerance_rows.ToleranceRows`, built inside the chunk that runs it,
so a cluster's workers share that work too.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import math

import numpy as np

from ...errors import SceneError
from ...drivetrain.operating_point import operating_point
from ...core.parallel import chunks, run_cases
from ...sim import layout as lo
from ...sim.batch import F_CUR, F_ERR, F_SAT
from ...sim.reference import initial_state
from ...sim.tolerance_rows import ToleranceRows, keep_effects
from ...scene.tolerances import STIFFNESS_SCALE
from ..batch_step import batch_step
from ..time.reference import run_spec
from ..time.run import MODES_KEPT, lumped_if_reshaped_at, sine_run_options

#: variants per chunk (smaller when every variant carries its own stroke tables)
CHUNK_SIZE = 2000
TABLE_CHUNK_SIZE = 500


@dataclass(frozen=True)
class ToleranceRuns:
    """The nonlinear time runs of the tolerance variants.

    Attributes
    ----------
    tracking_error : numpy.ndarray
        max |output - command| per variant (rad, or m for an output travel).
    peak_current : numpy.ndarray
        max |i| per variant (A).
    saturated : numpy.ndarray of bool
        A current or voltage limit was reached.
    failed : numpy.ndarray of bool
        The run could not be carried out (non-finite state, the stroke end, a step outside
        the RK4 stability region at the variant's parameters).
    reasons : tuple of str
    dt_s, duration_s : float
    steps_per_variant : int
    wall_s : float
        Integration time summed over the chunks.
    rows : ToleranceRows
        How the rows were built (``fitted`` None: exactly, one model per variant).
    notes : tuple of str
    spans : dict
        Key -> (lowest, highest) value the reduction was judged over (:func:`key_spans`).
    stiffness : (float, float) or None
        The smallest and largest factor on the series stiffness over ``spans``
        (:func:`stiffness_factors`); None when no tolerance varies the stiffness.
    """

    tracking_error: np.ndarray
    peak_current: np.ndarray
    saturated: np.ndarray
    failed: np.ndarray
    reasons: tuple
    dt_s: float
    duration_s: float
    steps_per_variant: int
    wall_s: float
    rows: object = field(repr=False, compare=False, default=None)
    notes: tuple = ()
    spans: dict = field(default_factory=dict)
    stiffness: tuple | None = None

    @property
    def count(self) -> int:
        return int(self.tracking_error.size)


def _chunk(case):
    """One chunk: its rows, then the batched runs (module level: picklable)."""
    from ..montecarlo.run import _chunk as run_chunk
    P, T, tix = case["built"] if "built" in case else case["rows"].rows(case["X"])
    run = {"model": case["model"], "P": P, "dt": case["dt"], "n_steps": case["n_steps"], "sub": case["sub"]}
    if T.shape[0] == 1 and not np.any(tix):
        run.update(deltas=np.zeros(len(P)), d_table=None)
    else:
        run["T"] = T[tix]
    return run_chunk(run)


def tolerance_runs(scene, values: dict, controller, *, keys=None, reference=None, duration: float | None = None,
                   full: bool = False, dt: float | None = None, executor=None, chunk_size: int | None = None,
                   progress: bool = True, seed: int = 0, spans: dict | None = None) -> ToleranceRuns:
    """Closed-loop time runs of the variants ``values`` (key path -> array, SI).

    Parameters
    ----------
    scene : Scene
    values : dict
    controller : CascadeController
        The same on every variant.
    keys : SceneKeys, optional
        Default: the scene's tolerances'.
    reference, duration, full, dt : optional
        As :func:`~.montecarlo.run.montecarlo`.
    executor : concurrent.futures.Executor, optional
    chunk_size : int, optional
    progress : bool
    seed : int
        Seed of the rows' random verification variants.
    spans : dict, optional
        Key -> (lowest, highest) value over which the reduction keeps what a varied
        stiffness acts on (default :func:`key_spans`; the worst corner's runs give the
        variants', so that both run the same model).

    Returns
    -------
    ToleranceRuns
    """
    keys = keys or scene.tolerances.scene_keys()
    ref, run_duration, _, _, _ = run_spec(scene, None)
    reference = reference or ref
    duration = run_duration if duration is None else float(duration)
    if not duration > 0:
        raise SceneError("duration", f"must be positive (got {duration:g} s)")
    spans = key_spans(scene, values) if spans is None else spans
    stiffness = stiffness_factors(scene, keys, spans)
    options, notes = sine_run_options(scene, controller, reference, full, stiffness=stiffness)
    if stiffness is not None and not full:
        options, notes = _stage_modes(scene, keys, controller, options, notes, spans, reference)
    if stiffness is not None and not full and options.chain == "full":
        options, notes = lumped_if_reshaped_at(scene, controller, options, notes, _key_ends(keys, spans),
                                               "its nodes or packed blocks differ")
    options, kept = keep_effects(options, values)
    notes += kept
    rows = ToleranceRows.create(scene, keys, values, controller, options, reference, seed=seed)
    notes.append(f"variant rows fitted from {rows.evaluations} exact models, verified to a relative "
                 f"{rows.error:.2g}" if rows.fitted is not None else
                 f"variant rows built one model per variant (the fitted rows verified only to {rows.error:.2g})")
    if rows.inert:
        notes.append("not acting in the model as run (exactly no effect on its figures): " + ", ".join(rows.inert))
    model, P0 = rows.model, rows.P0
    dt, step_note = batch_step(model, P0, initial_state(model, P0), duration, dt)
    notes.append(step_note)
    n_steps = max(1, int(round(duration / dt)))
    sub = int(round(model.sample_time / dt)) if P0[lo.CMODE] == lo.SAMPLED else 0
    X = np.column_stack([np.asarray(values[k], float) for k in rows.names])
    size = chunk_size or (TABLE_CHUNK_SIZE if rows.table_moves or rows.fitted is None else CHUNK_SIZE)
    # a chunk carries what a worker process can unpickle: fitted rows without the scene and the
    # controller (only exact builds need them), or rows built here, variant by variant
    shipped = None if rows.fitted is None else replace(rows, keys=None, controller=None, reference=None)
    cases = [{"model": rows.model, "dt": dt, "n_steps": n_steps, "sub": sub,
              **({"rows": shipped, "X": X[idx]} if shipped is not None else {"built": rows.rows(X[idx])})}
             for idx in chunks(np.arange(X.shape[0]), max(1, int(size)))]
    parts = run_cases(_chunk, cases, executor=executor, progress=progress, description="tolerance runs")
    from ..montecarlo.run import joined
    figs, _, _, reasons, failed = joined(parts, dt)
    return ToleranceRuns(figs[:, F_ERR], figs[:, F_CUR], figs[:, F_SAT] > 0, failed, reasons,
                         float(dt), duration, n_steps, float(sum(p["wall"] for p in parts)), rows,
                         (*notes, *model.notes), spans, stiffness)


def key_spans(scene, values: dict) -> dict:
    """Key -> (lowest, highest) of the variants ``values`` (key -> array) and, for a key the
    scene tolerances, of its ends (the worst corner's values: a range's ends, a normal's mean
    +- 3 sigma), so that the corners run on the variants' model."""
    ends = {t.key: t.ends for t in scene.tolerances.items} if scene.tolerances is not None else {}
    return {k: (float(min([np.min(v), *ends.get(k, ())])), float(max([np.max(v), *ends.get(k, ())])))
            for k, v in values.items()}


def stiffness_factors(scene, keys, values: dict):
    """(smallest, largest) factor on the drivetrain's series stiffness at the operating point
    that ``values`` (key -> the values it takes, or its span) reach, None when no key varies it.

    ``drivetrain.stiffness_scale`` is such a factor; a stage's stiffness key
    (``drivetrain[1].axial_stiffness``) moves the series stiffness by what that spring adds to
    the chain's compliance: the series stiffness with every such key at its lowest value (the
    series stiffness grows with each spring), over the nominal, is the smallest factor, with
    every such key at its highest the largest; the scale's ends multiply them.
    """
    stage = _stage_keys(values)
    if STIFFNESS_SCALE not in values and not stage:
        return None
    scale = np.asarray(values.get(STIFFNESS_SCALE, [1.0]), float)
    low, high = float(np.min(scale)), float(np.max(scale))
    if stage:
        q0 = operating_point(scene)[0]
        k0 = float(scene.drivetrain.stiffness([q0]).total[0])
        if math.isfinite(k0) and k0 > 0:
            ends = [float(keys.scene({k: float(pick(values[k])) for k in stage}).drivetrain.stiffness([q0]).total[0])
                    for pick in (np.min, np.max)]
            low, high = low * ends[0] / k0, high * ends[1] / k0
    return low, high


def _stage_keys(values: dict) -> list:
    """The varied keys that are a stage's own stiffness (``drivetrain[1].axial_stiffness``)."""
    return [k for k in values if k != STIFFNESS_SCALE and k.startswith("drivetrain")
            and "stiffness" in k.rsplit(".", 1)[-1]]


def _stage_modes(scene, keys, controller, options, notes, values, reference):
    """``(options, notes)`` with the chain's modes above the first kept when lumping them,
    measured on the chain with every stage stiffness key at its lowest value (over the
    lowest ``drivetrain.stiffness_scale``), costs more than simulate's rule allows.

    :func:`~servo_toolkit.studies.reduce.estimates.varied_stiffness` judges the lumping by
    the series factor, exact for a factor on every spring; one stage's spring changes the
    chain's form instead (on the belt and ball screw a belt 0.03 x as stiff costs 2.4e-4
    to lump, 8 x what the series factor 0.62 gives).
    """
    from ...sim.chain_choice import has_upper_modes, lumping_cost
    from ..reduce.estimates import DEFAULT_TOLERANCE
    stage = _stage_keys(values)
    if not stage or not options.compliance or options.chain != "two_mass":
        return options, notes
    q0 = operating_point(scene)[0]
    soft = keys.scene({k: float(np.min(values[k])) for k in stage})
    if not has_upper_modes(soft.drivetrain.chain, q0):
        return options, notes
    low = min(float(np.min(values.get(STIFFNESS_SCALE, [1.0]))), 1.0)
    cost = lumping_cost(soft, controller, q0, [reference.frequency], options.damping_ratio) / low
    budget = DEFAULT_TOLERANCE / 2
    if not cost > budget:
        return options, notes
    scaled = f", over the lowest stiffness_scale {low:.4g}" if low < 1 else ""
    note = (f"{MODES_KEPT} (left out above, judged at the nominal stiffness): the study varies "
            f"{', '.join(stage)}: lumping the modes costs ~{cost:.2g} with "
            f"{'each' if len(stage) > 1 else 'it'} at its lowest value (measured on that chain{scaled}), "
            f"more than {budget:g}")
    return replace(options, chain="full", chain_note=""), [*(n for n in notes if n != options.chain_note), note]


def _key_ends(keys, values: dict) -> dict:
    """label -> the scene at each varied scene key's lowest and highest value (the others
    nominal), for :func:`~servo_toolkit.studies.time.run.lumped_if_reshaped_at`."""
    ends = {}
    for k in values:
        if k == STIFFNESS_SCALE:
            continue
        for x in {float(np.min(values[k])), float(np.max(values[k]))}:
            ends[f"{k} = {x:.4g}"] = keys.scene({k: x})
    return ends


__all__ = ["ToleranceRuns", "key_spans", "stiffness_factors", "tolerance_runs"]
