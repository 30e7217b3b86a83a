"""Many closed-loop variants in one compiled call: the single run's RK4 step across variants.

Every variant is a row of a parameter matrix ``P`` (n_variants, nP) built by the model code
(:mod:`.variants`), with its own initial state and, where its tables differ (a rigid chain
whose load inertia varies), its own stroke tables (``T[tix[v]]``). :func:`run_variants`
runs them in parallel (numba ``prange``) through the same right-hand side
(:func:`kernel.rhs_phys`), controller sample (:func:`kernel.controller_sample`) and RK4
stages (the loop of :func:`integrators._rk4`) as a single :func:`servo_toolkit.sim.run`: one
physics. Instead of traces a variant keeps its figures (largest |tracking error|, peak
|current|, whether a limit was reached) and the states where its step is checked (peak
current, largest drivetrain deflection, the end); a non-finite state or the stroke end
stops that variant only. :mod:`.batch_lanes` runs the same loop for blocks of variants in
SIMD lanes.
"""

from __future__ import annotations

import numpy as np

from . import layout as lo
from .integrators import NCARRY, _rk4
from .kernel import jit, rhs
from .layout import (F_CUR, F_ERR, F_SAT, F_STATUS, F_STEP, F_TAU, NFIG, NSNAP, S_DEFLECTION,  # noqa: F401 - re-exported
                     S_END, S_PEAK)


@jit
def variant_run(x, P, T, dt, n_steps, sub, fig, snap):
    """One variant: the single run's loop (:func:`integrators._rk4`), keeping its figures and
    snapshots (and two records, its start and end).

    ``x`` is advanced in place; ``fig`` receives status (layout.OK, NONFINITE, STROKE_END),
    steps done, max |q - r| (rad or m), max |i| (A), 1 if the current reference or the
    voltage reached its limit, max |motor torque|; ``snap`` the states of :data:`S_PEAK`,
    :data:`S_DEFLECTION` and :data:`S_END` with their time and held current reference.
    """
    out_t = np.empty(2)
    out_x = np.empty((2, x.size))
    out_aux = np.empty((2, lo.NAUX))
    _rk4(x, P, T, 0.0, dt, 0, n_steps, n_steps, sub, 0.0, n_steps + 1, out_t, out_x, out_aux, fig, snap,
         np.zeros(NCARRY), np.zeros((5, x.size)), np.empty(max(x.size, 1)), np.empty(x.size),
         np.empty((4, max(P.size, x.size))))


def run_variants(X, P, T, tix, dt, n_steps, sub, figs, snaps):
    """:func:`variant_run` for every row of ``X`` (states, advanced in place) and ``P``, with
    tables ``T[tix[v]]``, one variant after another: the reference that the SIMD lanes
    (:func:`.batch_lanes.run_lanes`) are checked against. It calls the compiled
    :func:`variant_run` that the lanes compile for their per-variant fallback, so it adds no
    kernel of its own to compile."""
    for v in range(X.shape[0]):
        variant_run(X[v], P[v], T[tix[v]], float(dt), int(n_steps), int(sub), figs[v], snaps[v])


@jit
def jacobians(X, times, irefs, P, T, tix, vix, out):
    """d(rhs)/dx by central differences (steps as :func:`stability.jacobian`) at the states
    ``X[m]`` of variants ``vix[m]``, into ``out[m]`` (serial: a few hundred right-hand sides
    per variant against tens of thousands in its run)."""
    n = X.shape[1]
    for m in range(X.shape[0]):
        v = vix[m]
        f1 = np.empty(n)
        f2 = np.empty(n)
        aux = np.empty(lo.NAUX)
        for j in range(n):
            h = 1e-7 * (1.0 + abs(X[m, j]))
            xp = X[m].copy()
            xm = X[m].copy()
            xp[j] += h
            xm[j] -= h
            rhs(times[m], xp, P[v], T[tix[v]], irefs[m], f1, aux)
            rhs(times[m], xm, P[v], T[tix[v]], irefs[m], f2, aux)
            for k in range(n):
                out[m, k, j] = (f1[k] - f2[k]) / (2 * h)
