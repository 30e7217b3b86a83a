"""The RK4 step of the batched time runs (:mod:`.montecarlo`, :mod:`.tolerances.time_runs`),
chosen and checked by the single run's own step choice (:func:`servo_toolkit.sim.engine.choose_step`,
the one :func:`servo_toolkit.sim.engine.run` takes).

The step starts from the fastest eigenvalue at the nominal model's start (|lambda dt| =
:data:`~servo_toolkit.sim.engine.AUTO_Z`, dividing the sample time), then the nominal model
runs once at that step and the step is checked along that run, at the states the single run
checks. A step the study chose is reduced as the single run's ``auto`` reduces it (|lambda dt| = 1 for the fastest eigenvalue found along
the run, rerun and checked again); a step the caller gave that leaves the stability region
along the nominal run is refused, as the single run refuses it. Each variant is then also
checked at its own parameters (its start and its snapshots, each also in contact and at a
speed reversal: :func:`.montecarlo.variant_step.step_check`): a variant whose step lies outside the
region there fails with that reason.
"""

from __future__ import annotations

from ..errors import SceneError, SimulationError
from ..sim.engine import AUTO_Z, MAX_REDUCTIONS, choose_step, snap
from ..sim.fixed_run import MAX_STEPS


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
        that needs more than :data:`~servo_toolkit.sim.fixed_run.MAX_STEPS` steps (``duration``).
    SimulationError
        The study's own step still outside the region after
        :data:`~servo_toolkit.sim.engine.MAX_REDUCTIONS` reductions.
    """
    if dt is not None:
        if not dt > 0:
            raise SceneError("dt", f"must be positive (got {dt:g} s)")
        _steps(duration, snap(float(dt), model, duration), False)
    step = choose_step(model, P0, x0, duration, None if dt is None else float(dt),
                       method="auto" if dt is None else "rk4", max_steps=MAX_STEPS, stops_ok=True)
    history = _history(step.first_dt, step.reductions)
    if step.refused:
        raise SceneError("dt", f"RK4 step {step.dt:.4g} s leaves the stability region along the nominal run: "
                               f"{_where(step.outside)}; give a smaller step or none (the study then chooses it)")
    if step.method == "reference":
        if step.dt is None:  # the step budget
            _steps(duration, step.first_dt, False)
        if len(step.reductions) <= MAX_REDUCTIONS:
            _steps(duration, snap(AUTO_Z / step.reductions[-1]["max_abs_lambda"], model, duration), True)
        raise SimulationError(f"the batched RK4 found no stable step along the nominal run after "
                              f"{MAX_REDUCTIONS} reductions ({_where(step.reductions[-1])} at dt = "
                              f"{step.dt:.4g} s): the stiffness grows with the step; run servo-toolkit simulate "
                              "--method reference instead")
    if step.stopped:
        return step.dt, (f"RK4 step {step.dt:.4g} s{history}; the nominal run stopped ({step.stopped}): the step "
                         "is checked at each variant's start and snapshots only")
    return step.dt, (f"RK4 step {step.dt:.4g} s{history}, checked along the nominal run as a single run's "
                     f"(|lambda dt| up to {step.along['max_abs_lambda'] * step.dt:.3g}, inside the stability region) "
                     "and at each variant's start and snapshots")


def _steps(duration, dt, reduced):
    if duration / dt > MAX_STEPS:
        raise SceneError("duration", f"{duration / dt:.3g} RK4 steps of {dt:.3g} s exceed {MAX_STEPS:.0e}"
                         + (" (the step the nominal run's stability needs)" if reduced else ""))


def _where(figs):
    return (f"|lambda| = {figs['max_abs_lambda']:.3g} 1/s at t = {figs['t_s']:.3g} s needs dt <= "
            f"{figs['dt_limit_s']:.3g} s")


def _history(first, reductions):
    if not reductions:
        return ""
    return (f" (reduced from {first:.4g} s, as a single run's automatic step: along the nominal run "
            + "; then ".join(_where(r) for r in reductions) + ")")


__all__ = ["MAX_REDUCTIONS", "batch_step"]
