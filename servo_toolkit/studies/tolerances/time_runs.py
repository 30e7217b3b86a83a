"""Nonlinear closed-loop time runs of tolerance variants, batched.

The time-domain half of the tolerance study (:mod:`.run`): every variant of a
scene's ``[tolerances]`` (any scene keys) runs the designed controller on the nonlinear model
(saturation, friction, backlash, sampling, quantization), through the batched kernel as
:func:`~.montecarlo.run.montecarlo` runs its variants, with the same command as ``servo-toolkit
simulate`` (the 8 Hz, 2 deg sine for 1 s; 1 mm for an output travel) on the same reduced
model, every toleranced effect kept in it (:func:`~servo_toolkit.sim.tolerance_rows.keep_effects`).
Each variant's parameter row (and its stroke tables where they move) comes from
:class:`~servo_toolkit.sim.tolerance_rows.ToleranceRows`, built inside the chunk that runs it,
so a cluster's workers share that work too.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ...errors import SceneError
from ...core.parallel import chunks, run_cases
from ...sim import layout as lo
from ...sim.batch import F_CUR, F_ERR, F_SAT
from ...sim.reference import initial_state
from ...sim.tolerance_rows import ToleranceRows, keep_effects
from ..batch_step import batch_step
from ..time.reference import run_spec
from ..time.run import sine_run_options

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
                   progress: bool = True, seed: int = 0) -> ToleranceRuns:
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
    options, notes = sine_run_options(scene, controller, reference, full)
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
                         (*notes, *model.notes))


__all__ = ["ToleranceRuns", "tolerance_runs"]
