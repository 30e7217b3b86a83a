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
    evaluations made and the last time evaluated.
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
        rhs(t, np.ascontiguousarray(x, dtype=float), P, model.T, iref_box[0], dx, aux)
        return dx.copy()

    fun.count = 0
    fun.t_last = 0.0
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
    fun = make_fun(model, P, box, max_rhs_evals, deadline)
    events = _events(model, P)
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
            sol = solve_ivp(fun, (a, b), x, method=solver, t_eval=t_eval, rtol=rtol, atol=atol,
                            events=events)
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
            raise SimulationError(f"reference solver ({solver}) failed at t = {a:.6g} s: {sol.message}")
        out[k_out:stop] = sol.y[:, :want.size].T
        irefs[k_out:stop] = box[0]
        k_out = stop
        x = sol.y[:, -1].copy()
    return out, irefs
