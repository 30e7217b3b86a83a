"""Compiled fixed-step loops: classical RK4 and the cam paper's discrete scheme (seed 002).

Both loops hold the sampled controller's output between samples (zero-order hold), sample
it every ``sub`` steps, record every ``rec_every`` steps, track the peak motor torque at
every step, and stop with a status code on a non-finite state or on the stroke end. No
allocation happens inside the loop.

The paper's scheme (seed 002 section 3): over each step the configuration (p, q, the play
state s) is frozen, the velocities and electrical states take one RK4 step with J(p), N(p)
and the spring moment frozen, positions follow by summation (p += T p'), and the play
operator (seed eqs 6-8, c = half the play) updates s. It is first order in T.

numba's on-disk cache of :func:`integrate` is keyed on this file only, yet the loop compiles
in :func:`kernel.rhs` and everything it calls (layout constants, the cam kernels): after
editing those files, touch this one (or clear ``__pycache__``) so the loop is recompiled.
"""

from __future__ import annotations

import math

import numpy as np

from .kernel import controller_sample, jit, rhs
from .layout import (AUX_TAU, HALF_PLAY, NAUX, NONFINITE, OK, RIGID, STROKE_END, STROKE_HI,
                     STROKE_LO, STROKE_MODE)


@jit
def _finite(x):
    """One test per step: a NaN or inf anywhere makes the sum non-finite."""
    acc = 0.0
    for j in range(x.size):
        acc += x[j]
    return math.isfinite(acc)


@jit
def integrate(x, P, T, t0, dt, n_steps, sub, iref, paper, rec_every, out_t, out_x, out_aux):
    """Advance ``x`` in place by ``n_steps`` fixed steps.

    Returns
    -------
    status : int
        0 ok, 1 non-finite state, 2 stroke end reached (STROKE_MODE error).
    step : int
        Steps completed.
    n_rec : int
        Records written.
    max_tau : float
        Peak |motor torque| over every step (N*m).
    iref : float
        The held current reference at the end (A).
    """
    nx = x.size
    k1 = np.empty(nx)
    k2 = np.empty(nx)
    k3 = np.empty(nx)
    k4 = np.empty(nx)
    xs = np.empty(nx)
    aux = np.empty(NAUX)
    aux2 = np.empty(NAUX)
    work = np.empty(max(nx, 1))
    n_rec = 0
    max_tau = 0.0
    half = 0.5 * dt
    err_mode = P[STROKE_MODE] == 0.0
    qi = 0 if P[RIGID] > 0.0 else 2
    c = P[HALF_PLAY]
    to_sample = 0
    to_record = 0
    for step in range(n_steps + 1):
        t = t0 + step * dt
        if sub > 0:
            if to_sample == 0:
                iref = controller_sample(t, x, P, T, work)
                to_sample = sub
            to_sample -= 1
        rhs(t, x, P, T, iref, k1, aux)
        tau = abs(aux[AUX_TAU])
        if tau > max_tau:
            max_tau = tau
        if to_record == 0 or step == n_steps:
            to_record = rec_every
            out_t[n_rec] = t
            for j in range(nx):
                out_x[n_rec, j] = x[j]
            for j in range(NAUX):
                out_aux[n_rec, j] = aux[j]
            n_rec += 1
        to_record -= 1
        if not _finite(x) or not math.isfinite(tau):
            return NONFINITE, step, n_rec, max_tau, iref
        if err_mode and (x[qi] > P[STROKE_HI] or x[qi] < P[STROKE_LO]):
            return STROKE_END, step, n_rec, max_tau, iref
        if step == n_steps:
            break
        if paper:
            k1[0] = 0.0
            k1[2] = 0.0
            k1[6] = 0.0
        for j in range(nx):
            xs[j] = x[j] + half * k1[j]
        rhs(t + half, xs, P, T, iref, k2, aux2)
        if paper:
            k2[0] = 0.0
            k2[2] = 0.0
            k2[6] = 0.0
        for j in range(nx):
            xs[j] = x[j] + half * k2[j]
        rhs(t + half, xs, P, T, iref, k3, aux2)
        if paper:
            k3[0] = 0.0
            k3[2] = 0.0
            k3[6] = 0.0
        for j in range(nx):
            xs[j] = x[j] + dt * k3[j]
        rhs(t + dt, xs, P, T, iref, k4, aux2)
        p_old = x[0]
        for j in range(nx):
            x[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        if paper:
            x[0] = p_old + dt * x[1]
            x[2] = x[2] + dt * x[3]
            p = x[0]
            if p > p_old and p > x[6] + c:
                x[6] = p - c
            elif p < p_old and p < x[6] - c:
                x[6] = p + c
    return OK, n_steps, n_rec, max_tau, iref
