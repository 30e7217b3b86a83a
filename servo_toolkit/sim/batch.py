"""Many closed-loop variants in one compiled call: the single run's RK4 step across variants.

Every variant is a row of a parameter matrix ``P`` (n_variants, nP) built by the model code
(:mod:`.variants`), with its own initial state and, where its tables differ (a rigid chain
whose load inertia varies), its own stroke tables (``T[tix[v]]``). :func:`run_variants`
runs them in parallel (numba ``prange``) through the same right-hand side
(:func:`kernel.rhs_phys`), controller sample (:func:`kernel.controller_sample`) and RK4
stages (:func:`integrators.rk4_stages`) as a single :func:`servo_toolkit.sim.run`: one
physics. Instead of traces a variant keeps its figures (largest |tracking error|, peak
|current|, whether a limit was reached) and the states where its step is checked (peak
current, largest drivetrain deflection, the end); a non-finite state or the stroke end
stops that variant only. :mod:`.batch_lanes` runs the same loop for blocks of variants in
SIMD lanes.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from . import layout as lo
from .integrators import reversal, rk4_stages, sample_hold, split_at_reversal, step_status
from .kernel import FASTMATH, jit, reference, rhs, rhs_phys

#: columns of the per-variant figures
F_STATUS, F_STEP, F_ERR, F_CUR, F_SAT, F_TAU = range(6)
NFIG = 6
#: snapshots kept per variant (state, then time and held i_ref): peak |current|, largest
#: |p - q|, last state
S_PEAK, S_DEFLECTION, S_END = range(3)
NSNAP = 3


@jit
def _snap(snap, k, p, pd, q, qd, cur, xi, s, x, t, iref):
    nx = x.size
    snap[k, 0], snap[k, 1], snap[k, 2], snap[k, 3] = p, pd, q, qd
    snap[k, 4], snap[k, 5], snap[k, 6] = cur, xi, s
    for j in range(lo.NX_PHYS, nx):
        snap[k, j] = x[j]
    snap[k, nx] = t
    snap[k, nx + 1] = iref


@jit
def variant_run(x, P, T, dt, n_steps, sub, fig, snap):
    """One variant: the loop of :func:`integrators._rk4` keeping figures instead of traces.

    ``x`` is advanced in place; ``fig`` receives status (layout.OK, NONFINITE, STROKE_END),
    steps done, max |q - r| (rad or m), max |i| (A), 1 if the current reference or the
    voltage reached its limit, max |motor torque|; ``snap`` the states of :data:`S_PEAK`,
    :data:`S_DEFLECTION` and :data:`S_END` with their time and held current reference.
    """
    nx = x.size
    k1 = np.zeros(nx)
    k2 = np.zeros(nx)
    k3 = np.zeros(nx)
    k4 = np.zeros(nx)
    xs = np.zeros(nx)
    work = np.empty(max(nx, 1))
    err_mode = P[lo.STROKE_MODE] == 0.0
    rigid = P[lo.RIGID] > 0.0
    cont = int(P[lo.CMODE]) == lo.CONTINUOUS or P[lo.NMID] > 0.0  # states moving in x[7:]
    stick = P[lo.STICK] > 0.0
    ilim = P[lo.ILIM]
    vlim = P[lo.VLIM]
    p, pd, q, qd, cur, xi, s = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
    iref = 0.0
    to_sample = 0
    status = lo.OK
    max_err = 0.0
    max_cur = -1.0
    max_defl = -1.0
    max_tau = 0.0
    sat = 0.0
    step = 0
    t = 0.0
    for step in range(n_steps + 1):
        t = step * dt
        iref, to_sample = sample_hold(t, sub, to_sample, iref, p, pd, q, qd, cur, xi, s, x, P, T, work)
        a0, a1, a2, a3, a4, a5, i_, v_, r_, tau_ = rhs_phys(t, p, pd, q, qd, cur, xi, s, P, T,
                                                            iref, x, k1, False)
        err = abs(q - reference(t, P))
        if err > max_err:
            max_err = err
        tau = abs(tau_)
        if tau > max_tau:
            max_tau = tau
        if abs(r_) >= ilim or abs(v_) >= vlim:
            sat = 1.0
        if abs(i_) > max_cur:
            max_cur = abs(i_)
            _snap(snap, S_PEAK, p, pd, q, qd, i_, xi, s, x, t, iref)
        defl = abs(p - q)
        if defl > max_defl:
            max_defl = defl
            _snap(snap, S_DEFLECTION, p, pd, q, qd, cur, xi, s, x, t, iref)
        status = step_status(p, pd, q, qd, cur, xi, s, x, tau, P, err_mode, rigid)
        if status != lo.OK or step == n_steps:
            break
        if stick:  # a speed reversal of a node carrying friction: the step split there
            save = x.copy() if cont else x
            pn, pdn, qn, qdn, cn, xin = rk4_stages(t, dt, p, pd, q, qd, cur, xi, s, a0, a1, a2, a3, a4, a5,
                                                   P, T, iref, cont, x, xs, k1, k2, k3, k4)
            frac, node = reversal(pd, pdn, pd + dt * a1, qd, qdn, qd + dt * a3, P, rigid)
            if frac < 1.0:
                if cont:
                    x[:] = save
                p, pd, q, qd, cur, xi = split_at_reversal(t, dt, frac, node, p, pd, q, qd, cur, xi, s, P, T,
                                                          iref, cont, rigid, x, xs, k1, k2, k3, k4)
            else:
                p, pd, q, qd, cur, xi = pn, pdn, qn, qdn, cn, xin
            continue
        p, pd, q, qd, cur, xi = rk4_stages(t, dt, p, pd, q, qd, cur, xi, s, a0, a1, a2, a3, a4, a5,
                                           P, T, iref, cont, x, xs, k1, k2, k3, k4)
    x[0], x[1], x[2], x[3], x[4], x[5], x[6] = p, pd, q, qd, cur, xi, s
    _snap(snap, S_END, p, pd, q, qd, cur, xi, s, x, t, iref)
    fig[F_STATUS] = status
    fig[F_STEP] = step
    fig[F_ERR] = max_err
    fig[F_CUR] = max_cur
    fig[F_SAT] = sat
    fig[F_TAU] = max_tau


@nb.njit(parallel=True, cache=True, fastmath=FASTMATH, error_model="numpy")
def run_variants(X, P, T, tix, dt, n_steps, sub, figs, snaps):
    """:func:`variant_run` for every row of ``X`` (states, advanced in place) and ``P``, with
    tables ``T[tix[v]]``, in parallel across variants."""
    for v in nb.prange(X.shape[0]):
        variant_run(X[v], P[v], T[tix[v]], dt, n_steps, sub, figs[v], snaps[v])


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
