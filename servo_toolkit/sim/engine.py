"""Running a model: the step's choice and its stability checks along the run, the implicit
reference solve, and the result (one fixed-step run itself is :mod:`.fixed_run`)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError, SimulationError, StrokeEndReached
from . import layout as lo
from .fixed_run import MAX_RECORDS, Diverged, _fixed
from .ivp import MAX_RHS_EVALS, solve_reference
from .reference import Reference, check_start_on_tables, fill, initial_state
from .result import SimulationResult
from .run_result import aux_traces, check_finite, make_result, speed_and_reference
from .stability import fastest

METHODS = ("rk4", "paper", "reference", "auto")
#: target |lambda dt| for the automatic step (RK4's real-axis limit is 2.785)
AUTO_Z = 1.0
#: above this many steps ``auto`` hands the run to the implicit solver
AUTO_MAX_STEPS = 20_000_000
#: reductions of the automatic step before it hands the run to the implicit solver
MAX_REDUCTIONS = 3
#: states checked for the step limit along a fixed-step run
ALONG_SAMPLES = 48
#: |lambda dt| limit of the paper scheme's explicit position sum
PAPER_LIMIT = 2.0


def snap(dt, model, duration, output_dt=None):
    """The largest step <= dt that divides the sample time (else the record interval, else
    the duration)."""
    span = model.sample_time if model.sample_time > 0 else (output_dt or duration)
    n = max(1, math.ceil(span / dt * (1 - 1e-12)))
    return span / n


def _stability_probe(model, P, x0):
    return fastest(model, P, [x0], [0.0], [x0[4] if model.closed_loop else 0.0])


def paper_limit(probe) -> float:
    """Step limit of the paper's scheme: RK4's on the velocities and currents, and at most
    2 / |lambda| because the positions follow by an explicit sum after the velocity step
    (symplectic Euler on an oscillator is stable for |lambda dt| < 2)."""
    return min(probe["dt_limit_s"], PAPER_LIMIT / max(probe["max_abs_lambda"], 1e-300))


def _along_samples(states, aux, n=ALONG_SAMPLES):
    """Record indices where the step is checked along the run: an even spread, plus the
    records of peak current, of the largest drivetrain deflection (stiffest contact) and of
    the output angles farthest either way (deepest into an elastic end stop)."""
    m = len(states)
    pick = set(np.linspace(0, m - 1, min(n, m)).astype(int).tolist())
    pick.add(int(np.argmax(np.abs(aux[:, lo.AUX_I]))))
    pick.add(int(np.argmax(np.abs(states[:, 0] - states[:, 2]))))
    pick.update((int(np.argmax(states[:, 2])), int(np.argmin(states[:, 2]))))
    return np.array(sorted(pick))


@dataclass(frozen=True)
class StepChoice:
    """A fixed-step run's step, how it was chosen and checked (:func:`choose_step`), and the
    run at that step.

    Attributes
    ----------
    dt : float
        The step (s) last run (the refused one when ``refused``).
    method : {"rk4", "paper", "reference"}
        ``"reference"``: ``method="auto"`` handed the run to the implicit solver (the step
        needs more than the step budget, or stayed outside the stability region after
        :data:`MAX_REDUCTIONS` reductions).
    choice : str
        How the step was chosen, in words (:attr:`SimulationResult.choice`).
    probe : dict
        :func:`~.stability.fastest` at the start.
    stability : dict
        The figures a run reports: those along the run where its fastest eigenvalue exceeds
        the start's, else the start's.
    reductions : tuple of dict
        Each step the automatic choice gave up, with the figures along its run that made it
        (``dt_s`` the step, then :func:`~.stability.fastest`'s keys).
    first_dt : float
        The step before any reduction.
    refused : str
        Why the given (or default) step is refused ("" if it is not): outside the stability
        region at the start or along the run.
    along : dict or None
        :func:`~.stability.fastest` along the last run at ``dt`` (None: not run or not
        checked).
    outside : dict or None
        The figures where a refused step left the region (at the start or along the run).
    stopped : str
        The run's stop (a non-finite state, the stroke end) when ``stops_ok``; "" otherwise.
    notes : tuple of str
        A given step snapped to divide the sample time.
    run : tuple or None
        The last run at ``dt``: times, states, aux, max |tau|, wall time, steps, peaks.
    """

    dt: float | None
    method: str
    choice: str
    probe: dict
    stability: dict
    reductions: tuple = ()
    first_dt: float | None = None
    refused: str = ""
    along: dict | None = None
    outside: dict | None = None
    stopped: str = ""
    notes: tuple = ()
    run: tuple | None = field(default=None, repr=False)

    def to_dict(self) -> dict:
        """JSON-ready (without the run's arrays)."""
        return {"dt_s": self.dt, "method": self.method, "choice": self.choice, "probe": self.probe,
                "stability": self.stability, "reductions": list(self.reductions), "first_dt_s": self.first_dt,
                "refused": self.refused, "along": self.along, "outside": self.outside, "stopped": self.stopped,
                "notes": list(self.notes)}

    def __repr__(self) -> str:
        step = "no fixed step" if self.dt is None else f"dt {self.dt:.4g} s"
        state = f"refused: {self.refused}" if self.refused else (f"stopped: {self.stopped}" if self.stopped
                                                                   else self.choice)
        return f"StepChoice({self.method}, {step}; {state})"


def choose_step(model, P, x0, duration: float, dt: float | None = None, output_dt: float | None = None, *,
                method: str = "auto", check: bool = True, max_steps: int | None = None,
                stops_ok: bool = False) -> StepChoice:
    """The fixed RK4 (or paper-scheme) step of a run, chosen and checked along the run.

    The step starts from the fastest eigenvalue at the start (|lambda dt| = :data:`AUTO_Z`,
    at most the sample time, snapped to divide it); a given step is snapped down to divide
    it. The model then runs at that step and the step is checked at the states
    :func:`_along_samples` picks along the run. ``method="auto"`` reduces a step that
    leaves the stability region there (|lambda dt| = :data:`AUTO_Z` for the fastest
    eigenvalue found, run and checked again, at most :data:`MAX_REDUCTIONS` times) and hands
    the run to the implicit solver beyond that or beyond ``max_steps``; a given or default
    step (``"rk4"``, ``"paper"``) outside the region is refused (:attr:`StepChoice.refused`).

    Parameters
    ----------
    model : Model
    P : numpy.ndarray
        Its parameter row filled for the command.
    x0 : numpy.ndarray
        The start.
    duration : float
        Run length (s).
    dt : float, optional
        The caller's step (s); default chosen here.
    output_dt : float, optional
        Record interval (the step divides it when there is no sample time).
    method : {"auto", "rk4", "paper"}
    check : bool
        Check the step (False: the probe at the start stands for the run, nothing refused).
    max_steps : int, optional
        Most steps ``"auto"`` takes before it hands over (default :data:`AUTO_MAX_STEPS`).
    stops_ok : bool
        A run that stops (non-finite state, stroke end) ends the choice at its step
        (:attr:`StepChoice.stopped`) instead of raising.

    Returns
    -------
    StepChoice

    Raises
    ------
    SimulationError, StrokeEndReached
        The run stopped (unless ``stops_ok``).
    """
    max_steps = AUTO_MAX_STEPS if max_steps is None else max_steps
    probe = _stability_probe(model, P, x0)
    limit = probe["dt_limit_s"]
    cap = model.sample_time if model.sample_time > 0 else duration / 200
    auto_dt = snap(min(cap, AUTO_Z / max(probe["max_abs_lambda"], 1e-300)), model, duration, output_dt)
    choice, notes = "", []
    if method == "auto":
        if duration / auto_dt > max_steps:
            return StepChoice(None, "reference", f"fastest eigenvalue |lambda| = {probe['max_abs_lambda']:.3g} 1/s "
                              f"needs dt <= {limit:.3g} s, more than {max_steps} RK4 steps: implicit solver instead",
                              probe, probe, first_dt=auto_dt)
        dt = auto_dt
        capped = cap < AUTO_Z / max(probe["max_abs_lambda"], 1e-300)
        why = ("at most the sample time" if model.sample_time > 0 else "at most the duration / 200") if capped \
            else f"|lambda dt| = {AUTO_Z:g}"
        choice = (f"RK4 with dt = {dt:.4g} s ({why}): |lambda dt| = {probe['max_abs_lambda'] * dt:.3g} for the "
                  f"fastest eigenvalue at the start, |lambda| = {probe['max_abs_lambda']:.3g} 1/s "
                  f"(stability limit there dt = {limit:.4g} s)")
    elif dt is None:
        dt = auto_dt
        choice = f"default step {dt:.4g} s (|lambda dt| = {probe['max_abs_lambda'] * dt:.3g})"
    else:
        snapped = snap(dt, model, duration, output_dt)
        if abs(snapped - dt) > 1e-12 * dt:
            notes.append(f"step {dt:.4g} s snapped to {snapped:.4g} s to divide the sample time")
        dt = snapped
        choice = f"user step {dt:.4g} s"
    paper, reduce = method == "paper", method == "auto"
    scheme = "paper scheme" if paper else "RK4"
    if paper:
        limit = paper_limit(probe)
    common = dict(probe=probe, first_dt=dt, notes=tuple(notes))
    if check and dt > limit:
        return StepChoice(dt, method, choice, stability=probe, outside=probe, **common, refused=(
            f"{scheme} step {dt:.4g} s is outside the stability region: fastest eigenvalue "
            f"lambda = {probe['lambda'][0]:.4g}{probe['lambda'][1]:+.4g}j 1/s at t = 0 gives "
            f"|lambda dt| = {probe['max_abs_lambda'] * dt:.3g}; use dt <= {limit:.4g} s or method='auto'"))
    method = "paper" if paper else "rk4"
    reductions = []
    while True:
        diverged = None
        try:
            fixed = _fixed(model, P, x0, duration, dt, output_dt, paper)
            times, states, aux = fixed[:3]
        except (SimulationError, StrokeEndReached) as exc:
            if reduce and check and isinstance(exc, Diverged) and len(exc.times) >= 2:
                # the automatic step went non-finite: the stiffness along its finite records
                # decides, as along a run that ends (below)
                diverged = f"the run at dt = {dt:.4g} s went non-finite ({exc})"
                times, states, aux = exc.times, exc.states, exc.aux
                choice += f"; {diverged}"
            elif not stops_ok:
                raise
            else:
                return StepChoice(dt, method, choice, stability=probe, reductions=tuple(reductions),
                                  stopped=str(exc), **common)
        if not check:  # nothing to check: the probe at the start stands for the run
            along = probe
            break
        pick = _along_samples(states, aux)
        along = fastest(model, P, states[pick], times[pick], aux[pick, lo.AUX_IREF])
        if paper:
            along["dt_limit_s"] = paper_limit(along)
        if dt <= along["dt_limit_s"]:
            if diverged is not None:  # a non-finite run the stiffness along its records does not explain
                raise SimulationError(f"{diverged}: inside the stability region along its records "
                                      f"(|lambda dt| up to {along['max_abs_lambda'] * dt:.3g})")
            break
        if not reduce:
            return StepChoice(dt, method, choice, stability=probe, reductions=tuple(reductions), outside=along,
                              **common, refused=(
                f"{scheme} step {dt:.4g} s left the stability region along the run: |lambda| = "
                f"{along['max_abs_lambda']:.4g} 1/s at t = {along['t_s']:.4g} s needs dt <= "
                f"{along['dt_limit_s']:.4g} s; use a smaller dt or method='auto'"))
        reductions.append({"dt_s": dt, **along})
        new_dt = snap(AUTO_Z / along["max_abs_lambda"], model, duration, output_dt)
        if len(reductions) > MAX_REDUCTIONS or duration / new_dt > max_steps:
            choice += f"; along the run |lambda| rose to {along['max_abs_lambda']:.3g} 1/s: implicit solver instead"
            return StepChoice(dt, "reference", choice, stability=probe, reductions=tuple(reductions), **common)
        choice += (f"; reduced to dt = {new_dt:.4g} s after |lambda| = {along['max_abs_lambda']:.3g} 1/s at "
                   f"t = {along['t_s']:.3g} s")
        dt = new_dt
    stability = {**along, "dt_limit_s": min(limit, along["dt_limit_s"])} \
        if along["max_abs_lambda"] > probe["max_abs_lambda"] else probe
    return StepChoice(dt, method, choice, stability=stability, reductions=tuple(reductions), run=fixed,
                      along=along if check else None, **common)


def run(model, reference: Reference, duration: float, method: str = "rk4", dt: float | None = None,
        *, output_dt: float | None = None, x0=None, at_rest: bool = False, solver: str = "LSODA",
        rtol: float = 1e-10, atol: float = 1e-10, check_stability: bool = True,
        max_rhs_evals: int | None = MAX_RHS_EVALS, time_limit_s: float | None = None) -> SimulationResult:
    """Run an assembled model (no recompilation: only the parameter copy changes).

    Parameters
    ----------
    model : Model
        From :func:`build_model`.
    reference : Reference
        Position command (closed loop) or :meth:`Reference.voltage` (open loop).
    duration : float
        Run length (s).
    method : {"rk4", "paper", "reference", "auto"}
        Fixed-step RK4; the cam paper's frozen-configuration scheme; scipy ``solve_ivp``
        (``solver``, tolerances ``rtol``/``atol``); or automatic choice.
    dt : float, optional
        Fixed step (s); snapped down to divide the controller sample time. Default: from the
        fastest eigenvalue (|lambda dt| = 1) and never above the sample time.
    output_dt : float, optional
        Record interval (a multiple of dt; the grid the reference is evaluated on).
    x0 : array_like, optional
        Initial state; default static equilibrium at the reference's start.
    at_rest : bool
        Start unloaded at rest instead of in equilibrium.
    check_stability : bool
        Refuse steps outside RK4's stability region (methods "rk4" and "paper"). False skips
        the eigenvalue probe along the run as well (most of a short run's cost): the result's
        stability figures are those at the start.
    max_rhs_evals, time_limit_s : int or None, float or None
        Budget of the reference solve (right-hand-side evaluations, wall seconds); a spent
        budget raises SimulationError with the time reached instead of hanging.

    Returns
    -------
    SimulationResult

    Raises
    ------
    SimulationError
        Non-finite state (with time and state name), stroke end, or (``rk4``) a step outside
        the stability region of the fastest mode.
    """
    if method not in METHODS:
        raise SceneError("method", f"must be one of {', '.join(METHODS)} (got {method!r})")
    if not duration > 0:
        raise SceneError("duration", f"must be positive (got {duration:g} s)")
    if dt is not None and not dt > 0:
        raise SceneError("dt", f"must be positive (got {dt:g} s)")
    if method == "paper" and model.P[lo.NMID] > 0:
        raise SimulationError("the cam paper's scheme integrates a two-mass or rigid model; this one is the "
                              "full drivetrain chain: use method 'rk4' or build it with chain='two_mass'")
    P = fill(model, reference)
    if x0 is None:
        x0 = initial_state(model, P, at_rest)
    else:
        x0 = np.asarray(x0, dtype=float).copy()
        check_start_on_tables(model, P, x0)
    notes = list(model.notes)
    requested = method
    if method == "reference":
        probe, choice = _stability_probe(model, P, x0), ""
    else:
        step = choose_step(model, P, x0, duration, dt, output_dt, method=method, check=check_stability)
        notes += step.notes
        if step.refused:
            raise SimulationError(step.refused)
        method, probe, choice = step.method, step.probe, step.choice
        if method != "reference":
            times, states, aux, max_tau, wall, steps, peaks = step.run
            speed, refs = speed_and_reference(model, P, times, states)
            return make_result(model, times, states, aux, speed, refs, max_tau, wall, method, step.dt, steps,
                           requested, choice, step.stability, reference, notes, peaks)
    # implicit / adaptive reference
    if output_dt is None:
        n = min(MAX_RECORDS, max(200, int(duration / (model.sample_time or duration / 1000))))
        t_out = np.linspace(0.0, duration, n + 1)
    else:
        n = int(round(duration / output_dt))
        t_out = np.arange(n + 1) * output_dt
    start = time.perf_counter()
    states, irefs = solve_reference(model, P, x0, t_out, solver=solver, rtol=rtol, atol=atol,
                                    max_rhs_evals=max_rhs_evals, time_limit_s=time_limit_s)
    wall = time.perf_counter() - start
    check_finite(model, t_out, states)
    aux, speed, refs = aux_traces(model, P, t_out, states, irefs)
    choice = choice or f"scipy solve_ivp {solver}, rtol {rtol:g}, atol {atol:g}"
    return make_result(model, t_out, states, aux, speed, refs, float(np.max(np.abs(aux[:, lo.AUX_TAU]))),
                   wall, f"reference:{solver}", None, 0, requested, choice, probe, reference, notes)
