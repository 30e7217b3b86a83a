"""One fixed-step run of the compiled loop at a given step: its grid of steps and records,
the run (RK4 or the paper's scheme), its peaks over every step, and its stops (a non-finite
state, the stroke end, a divergence) as errors. :mod:`.engine` chooses and checks the step.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..core.output_units import OutputUnit
from ..errors import SimulationError, StrokeEndReached
from . import layout as lo
from .integrators import integrate

#: most fixed steps one run may take (about a minute of the compiled loop): a step or a
#: duration that asks for more is refused instead of running for hours
MAX_STEPS = 300_000_000
MAX_RECORDS = 4000


def _grid(model, duration, dt, output_dt):
    if not duration / dt <= MAX_STEPS:
        raise SimulationError(f"{duration:g} s at a step of {dt:g} s is {duration / dt:.3g} steps, more than the "
                              f"{MAX_STEPS:.0e} one run may take: give a larger --dt or a shorter duration")
    n_steps = max(1, int(round(duration / dt)))
    if output_dt is None:
        rec = max(1, math.ceil(n_steps / MAX_RECORDS))
    else:
        rec = int(round(output_dt / dt))
        if rec < 1 or abs(rec * dt - output_dt) > 1e-9 * output_dt:
            raise ValueError(f"output_dt = {output_dt:g} s is not a multiple of dt = {dt:g} s")
    return n_steps, rec


class Diverged(SimulationError):
    """A fixed-step run went non-finite: the message names the states and the time; ``times``,
    ``states`` and ``aux`` are its finite records before it (what ``method="auto"`` reads the
    stiffness along the run from, to reduce its step)."""

    def __init__(self, message: str, times, states, aux):
        super().__init__(message)
        self.times, self.states, self.aux = times, states, aux


def _fixed(model, P, x0, duration, dt, output_dt, paper):
    n_steps, rec = _grid(model, duration, dt, output_dt)
    n_rec = n_steps // rec + 2
    out_t, out_x, out_aux = np.empty(n_rec), np.empty((n_rec, model.nx)), np.empty((n_rec, lo.NAUX))
    sub = int(round(model.sample_time / dt)) if P[lo.CMODE] == lo.SAMPLED else 0
    # a zero-step call on copies first, so wall_s times the run's steps alone
    integrate(x0.copy(), P.copy(), model.T, 0.0, dt, 0, sub, 0.0, paper, rec, out_t[:1].copy(),
              out_x[:1].copy(), out_aux[:1].copy())
    x = x0.copy()
    fig = np.full(lo.NFIG, np.nan)
    start = time.perf_counter()
    status, step, k, max_tau, _ = integrate(x, P, model.T, 0.0, dt, n_steps, sub, 0.0, paper,
                                            rec, out_t, out_x, out_aux, fig)
    wall = time.perf_counter() - start
    t_fail = step * dt
    if status == lo.NONFINITE:
        row = out_x[k - 1] if k else x
        names = [model.state_names[j] for j in np.flatnonzero(~np.isfinite(x))] or \
                [model.state_names[j] for j in np.flatnonzero(~np.isfinite(row))]
        finite = np.all(np.isfinite(out_x[:k]), axis=1) & np.all(np.isfinite(out_aux[:k]), axis=1)
        raise Diverged(f"non-finite state {', '.join(names) or 'motor torque'} at t = "
                       f"{t_fail:.6g} s (step {dt:.3g} s)", out_t[:k][finite], out_x[:k][finite], out_aux[:k][finite])
    if status == lo.STROKE_END:
        qi = 0 if model.rigid else 2
        lo_q, hi_q = model.stroke
        unit = OutputUnit(model.output_unit)  # an angle in deg, a travel in mm
        what, shown, k = ("travel" if unit.linear else "angle"), unit.shown, unit.factor
        if max(x[qi] - hi_q, lo_q - x[qi]) > hi_q - lo_q:
            # one step cannot carry a physical motion a whole stroke past its end
            scheme = "paper scheme" if paper else "RK4"
            state = ", ".join(f"{n} = {v:.4g}" for n, v in zip(model.state_names[:6], x[:6]))
            raise SimulationError(f"{scheme} diverged at t = {t_fail:.6g} s with step {dt:.3g} s "
                                  f"(output {what} {x[qi] * k:.4g} {shown}; {state}); use a "
                                  f"smaller dt or method='auto'")
        raise StrokeEndReached(f"stroke end reached at t = {t_fail:.6g} s: output {what} "
                               f"{x[qi] * k:.3f} {shown} outside [{model.stroke[0] * k:.1f}, "
                               f"{model.stroke[1] * k:.1f}] {shown} (use options stroke_end='stop' "
                               f"for an elastic end stop)", t_fail)
    # peaks over every step (RK4 keeps them; the paper's scheme leaves fig NaN: the records)
    peaks = {} if paper or not model.closed_loop else {
        "max_abs_current_A": float(fig[lo.F_CUR]), "max_abs_tracking_error": float(fig[lo.F_ERR])}
    return out_t[:k], out_x[:k], out_aux[:k], max_tau, wall, n_steps, peaks
