"""Reference solutions with scipy's ``solve_ivp`` on the same compiled right-hand side.

Sampled controllers are handled exactly: the integration restarts at every sample instant
after :func:`kernel.controller_sample` (the same compiled update the RK4 loop uses), so the
reference differs from RK4 only by the integrator. Continuous and open-loop models are one
``solve_ivp`` call. Default: LSODA (switches to BDF on stiffness), rtol 1e-10, atol 1e-10.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.integrate import solve_ivp
from ..core.progress import progress_bar

from ..errors import SimulationError
from . import layout as lo
from .ivp_friction import FrictionModes, breakaway_gauge, friction_nodes  # noqa: F401 - friction_nodes: re-exported
from .kernel import controller_sample, rhs


#: default budget of right-hand-side evaluations for one reference solve
MAX_RHS_EVALS = 3_000_000
#: most controller samples (solver restarts) one reference solve may plan: about an hour and a
#: half of restarts, and their edge times fit in 400 MB
MAX_SEGMENTS = 50_000_000


class _Budget(Exception):
    """Raised inside the right-hand side when the evaluation or wall-time budget is spent."""


def make_fun(model, P, iref_box, max_evals=None, deadline=None):
    """``f(t, x)`` for scipy, evaluating the compiled kernel with the held i_ref.

    With ``max_evals`` (count) or ``deadline`` (``time.perf_counter()`` value) the function
    raises ``_Budget`` once either is exceeded; ``fun.count`` and ``fun.t_last`` report the
    evaluations made and the last time evaluated. ``fun.rest`` (empty unless set: the indices
    in x of the speeds of nodes held at rest, :class:`~.ivp_friction.FrictionModes`) are read
    as 0 whatever the solver's trial state holds there.
    """
    dx = np.empty(model.nx)
    aux = np.empty(lo.NAUX)

    def fun(t, x):
        fun.count += 1
        fun.t_last = t
        if max_evals is not None and fun.count > max_evals:
            raise _Budget("evaluations")
        if deadline is not None and fun.count % 1000 == 0 and time.perf_counter() > deadline:
            raise _Budget("time")
        x = np.ascontiguousarray(x, dtype=float)
        if fun.rest:
            x = x.copy()
            x[fun.rest] = 0.0
        rhs(t, x, P, model.T, iref_box[0], dx, aux)
        return dx.copy()

    fun.count = 0
    fun.t_last = 0.0
    fun.rest = []
    return fun


def _events(model, P):
    if P[lo.STROKE_MODE] != lo.STROKE_ERROR:
        return None
    qi = 0 if model.rigid else 2

    def hi(t, x):
        return P[lo.STROKE_HI] - x[qi]

    def low(t, x):
        return x[qi] - P[lo.STROKE_LO]

    hi.terminal = low.terminal = True
    return [hi, low]


#: most restarts at friction events (speed reversals, breakaways) within one controller sample
MAX_FRICTION_RESTARTS = 10_000


def solve_reference(model, P, x0, t_out, solver="LSODA", rtol=1e-10, atol=1e-10, progress=None,
                    max_rhs_evals=MAX_RHS_EVALS, time_limit_s=None):
    """Integrate to every time in ``t_out`` (starting at ``t_out[0]``).

    Parameters
    ----------
    max_rhs_evals : int or None
        Budget of right-hand-side evaluations (None = unlimited).
    time_limit_s : float or None
        Wall-time budget (s; None = unlimited).

    Returns
    -------
    states : numpy.ndarray, shape (len(t_out), nx)
    irefs : numpy.ndarray
        Held current reference at each output time.

    Raises
    ------
    SimulationError
        Stroke end, solver failure, or a spent budget (with the time reached), never a hang.
    """
    t_out = np.asarray(t_out, dtype=float)
    x = np.array(x0, dtype=float)
    box = [0.0]
    deadline = None if time_limit_s is None else time.perf_counter() + time_limit_s
    P = np.array(P, dtype=float)  # its friction directions are set along the solve
    fun = make_fun(model, P, box, max_rhs_evals, deadline)
    events = _events(model, P)
    modes = FrictionModes(model, P, fun, lambda Z: make_fun(model, Z, box), breakaway_gauge(model, P, box))
    out = np.full((t_out.size, model.nx), np.nan)
    irefs = np.zeros(t_out.size)
    ts = model.sample_time if P[lo.CMODE] == lo.SAMPLED else 0.0
    t0, t1 = t_out[0], t_out[-1]
    if ts > 0:
        if not (t1 - t0) / ts <= MAX_SEGMENTS:
            raise SimulationError(f"the reference solver restarts at every controller sample: {t1 - t0:g} s at a "
                                  f"sample time of {ts:g} s is {(t1 - t0) / ts:.3g} restarts, more than the "
                                  f"{MAX_SEGMENTS:.0e} one run may take: a larger sensors.sample_time or a "
                                  "shorter duration")
        n_seg = int(np.ceil((t1 - t0) / ts - 1e-9))
        edges = t0 + ts * np.arange(n_seg + 1)
        edges[-1] = t1
    else:
        edges = np.array([t0, t1])
    work = np.empty(max(model.nx, 1))
    show = (len(edges) > 2000) if progress is None else progress
    k_out = 0
    for k in progress_bar(range(len(edges) - 1), show=show, desc="reference solve", leave=False):
        a, b = edges[k], edges[k + 1]
        if ts > 0:
            box[0] = controller_sample(a, x, P, model.T, work)
        last = k == len(edges) - 2
        stop = np.searchsorted(t_out, b, side="right" if last else "left")
        want = t_out[k_out:stop]
        t_eval = want if (want.size and want[-1] == b) else np.append(want, b)
        try:
            sol, x = _solve_segment(fun, a, b, x, t_eval, solver, rtol, atol, events, modes)
        except _Budget as why:
            spent = (f"{fun.count - 1} right-hand-side evaluations" if str(why) == "evaluations"
                     else f"the time limit of {time_limit_s:g} s")
            raise SimulationError(
                f"reference solver ({solver}, rtol {rtol:g}, atol {atol:g}) stalled at t = "
                f"{fun.t_last:.6g} s after {spent}: the right-hand side is probably switching "
                f"or very stiff there; try solver='Radau', looser tolerances, or method='rk4'") from None
        if sol.status == 1:
            hit = [float(t) for ev in sol.t_events for t in ev]
            raise SimulationError(f"reference solution reached the stroke end at t = {min(hit):.6g} s")
        if sol.status != 0 or not np.all(np.isfinite(sol.y)):
            why = sol.message if sol.status != 0 else "the state became non-finite"
            raise SimulationError(f"reference solver ({solver}, rtol {rtol:g}, atol {atol:g}) failed at t = "
                                  f"{_reached(sol, fun):.9g} s (in its solve from {a:.6g} s to {b:.6g} s): "
                                  f"{why}")
        out[k_out:stop] = sol.y[:, :want.size].T
        irefs[k_out:stop] = box[0]
        k_out = stop
    return out, irefs


def _reached(sol, fun) -> float:
    """Where a failed solve stopped: its first output time with a non-finite state, else the
    last time the right-hand side was evaluated at (the solver's last trial)."""
    bad = ~np.all(np.isfinite(sol.y), axis=0) if sol.y.size else np.zeros(0, dtype=bool)
    return float(sol.t[np.argmax(bad)]) if bad.any() else float(fun.t_last)


class _Joined:
    """The pieces of a segment solved between friction events, as one solve_ivp result."""

    def __init__(self, ts, ys, status, message, t_events):
        self.t = np.concatenate(ts) if ts else np.zeros(0)
        self.y = np.concatenate(ys, axis=1) if ys else np.zeros((0, 0))
        self.status, self.message, self.t_events = status, message, t_events


def _solve(fun, span, x, solver, t_eval, rtol, atol, events):
    """``solve_ivp`` whose failure on a non-finite state inside a stiff solver's linear
    algebra (scipy raises ValueError there) is reported as a failed solve (status -1)."""
    try:
        return solve_ivp(fun, span, x, method=solver, t_eval=t_eval, rtol=rtol, atol=atol, events=events)
    except ValueError as why:
        if "infs or NaNs" not in str(why):
            raise
        return _Joined([], [], -1, f"the state became non-finite ({why})", [])


def _solve_segment(fun, a, b, x, t_eval, solver, rtol, atol, events, modes):
    """One controller sample: ``solve_ivp`` from a to b, restarted at every friction event
    (:class:`~.ivp_friction.FrictionModes`: a reversal, a breakaway) with the node at rest.
    Returns the joined result and the state at b."""
    if not modes.nodes:
        sol = _solve(fun, (a, b), x, solver, t_eval, rtol, atol, events)
        return sol, (sol.y[:, -1].copy() if sol.t.size else x)
    ts, ys = [], []
    t0, x = a, np.array(x, dtype=float)
    modes.start(x)
    for _ in range(MAX_FRICTION_RESTARTS):
        ev_f = modes.events(t0, x)
        evs = (events or []) + ev_f
        te = t_eval[t_eval >= t0]
        sol = _solve(fun, (t0, b), x, solver, te, rtol, atol, evs)
        # no output time before an event: solve_ivp leaves its empty lists as they are
        sol.t, sol.y = np.asarray(sol.t, dtype=float), np.asarray(sol.y, dtype=float).reshape(x.size, -1)
        if sol.status != 1:
            ts.append(sol.t)
            ys.append(sol.y)
            return _Joined(ts, ys, sol.status, sol.message, sol.t_events), (sol.y[:, -1].copy() if sol.t.size else x)
        n_stroke = len(events or [])
        hits = [(ev[0], k) for k, ev in enumerate(sol.t_events) if len(ev)]
        t_hit, k = min(hits)
        if k < n_stroke:  # the stroke end
            return _Joined(ts + [sol.t], ys + [sol.y], 1, sol.message, sol.t_events), x
        keep = sol.t < t_hit
        ts.append(sol.t[keep])
        ys.append(sol.y[:, keep])
        x = np.array(sol.y_events[k][0], dtype=float)
        modes.restart(ev_f[k - n_stroke], t_hit, x)  # at rest: the friction decides between stick and slip
        t0 = t_hit
        if t0 >= b:
            ts.append(np.array([b]))
            ys.append(x[:, None])
            return _Joined(ts, ys, 0, "event at the segment's end", sol.t_events), x
    raise SimulationError(f"the reference solver met more than {MAX_FRICTION_RESTARTS} friction events "
                          f"(stick and slip) in one solve from t = {a:.6g} s, the last at t = {t0:.9g} s; "
                          f"try another solver (solver='LSODA') or method='rk4'")
