"""The RK4 step of the batched time runs (:mod:`.montecarlo`, :mod:`.tolerance_runs`),
chosen and checked as a single run's (:func:`servo_toolkit.sim.engine.run`).

The step starts from the fastest eigenvalue at the nominal model's start (|lambda dt| =
:data:`~servo_toolkit.sim.engine.AUTO_Z`, dividing the sample time), then the nominal model
runs once at that step and the step is checked along that run, at the states the single run
checks (:func:`~servo_toolkit.sim.engine.along_run`). A step the study chose is reduced as
the single run's ``auto`` reduces it (|lambda dt| = 1 for the fastest eigenvalue found along
the run, rerun and checked again); a step the caller gave that leaves the stability region
along the nominal run is refused, as the single run refuses it. Each variant is then also
checked at its own parameters (its start and its snapshots, :func:`.montecarlo._step_check`):
a variant whose step lies outside the region there fails with that reason.
"""

from __future__ import annotations

from ..errors import SceneError, SimulationError, StrokeEndReached
from ..sim.engine import AUTO_Z, MAX_STEPS, _snap, _stability_probe, along_run

#: reductions of the study's own step before it gives up (the single run's count)
MAX_REDUCTIONS = 3


def batch_step(model, P0, x0, duration: float, dt: float | None = None):
    """The batched runs' RK4 step and the note saying how it was chosen and checked.

    Parameters
    ----------
    model : Model
        The nominal model (the variants' shared build).
    P0 : numpy.ndarray
        Its parameter row filled for the command.
    x0 : numpy.ndarray
        Its start.
    duration : float
        Run length (s).
    dt : float, optional
        The caller's step (s; snapped to divide the sample time); default: chosen here.

    Returns
    -------
    dt : float
    note : str

    Raises
    ------
    SceneError
        ``dt`` not positive, or outside the stability region along the nominal run; a step
        that needs more than :data:`~servo_toolkit.sim.engine.MAX_STEPS` steps (``duration``).
    SimulationError
        The study's own step still outside the region after :data:`MAX_REDUCTIONS` reductions.
    """
    chosen = dt is None
    if chosen:
        probe = _stability_probe(model, P0, x0)
        cap = model.sample_time if model.sample_time > 0 else duration / 200
        dt = _snap(min(cap, AUTO_Z / max(probe["max_abs_lambda"], 1e-300)), model, duration)
    elif not dt > 0:
        raise SceneError("dt", f"must be positive (got {dt:g} s)")
    else:
        dt = _snap(float(dt), model, duration)
    first, reduced = dt, []
    while True:
        if duration / dt > MAX_STEPS:
            raise SceneError("duration", f"{duration / dt:.3g} RK4 steps of {dt:.3g} s exceed {MAX_STEPS:.0e}"
                             + (" (the step the nominal run's stability needs)" if reduced else ""))
        try:
            along = along_run(model, P0, x0, duration, dt)
        except (SimulationError, StrokeEndReached) as exc:
            return dt, (f"RK4 step {dt:.4g} s{_history(first, reduced)}; the nominal run stopped ({exc}): the step "
                        "is checked at each variant's start and snapshots only")
        lam, limit = along["max_abs_lambda"], along["dt_limit_s"]
        where = f"|lambda| = {lam:.3g} 1/s at t = {along['t_s']:.3g} s needs dt <= {limit:.3g} s"
        if dt <= limit:
            return dt, (f"RK4 step {dt:.4g} s{_history(first, reduced)}, checked along the nominal run as a single "
                        f"run's (|lambda dt| up to {lam * dt:.3g}, inside the stability region) and at each "
                        "variant's start and snapshots")
        if not chosen:
            raise SceneError("dt", f"RK4 step {dt:.4g} s leaves the stability region along the nominal run: "
                             f"{where}; give a smaller step or none (the study then chooses it)")
        if len(reduced) >= MAX_REDUCTIONS:
            raise SimulationError(f"the batched RK4 found no stable step along the nominal run after "
                                  f"{MAX_REDUCTIONS} reductions ({where} at dt = {dt:.4g} s): the stiffness "
                                  "grows with the step; run servo-toolkit simulate --method reference instead")
        reduced.append(where)
        dt = _snap(AUTO_Z / lam, model, duration)


def _history(first, reduced):
    if not reduced:
        return ""
    return (f" (reduced from {first:.4g} s, as a single run's automatic step: along the nominal run "
            + "; then ".join(reduced) + ")")


__all__ = ["MAX_REDUCTIONS", "batch_step"]
