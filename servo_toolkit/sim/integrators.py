"""Compiled fixed-step loops: classical RK4 and the cam paper's discrete scheme (seed 002).

Both loops hold the sampled controller's output between samples (zero-order hold), sample
it every ``sub`` steps, record every ``rec_every`` steps, track the peak motor torque at
every step, and stop with a status code on a non-finite state or on the stroke end. No
allocation happens inside the loop.

The paper's scheme (seed 002 section 3): over each step the configuration (p, q, the play
state s) is frozen, the velocities and electrical states take one RK4 step with J(p), N(p)
and the spring moment frozen, positions follow by summation (p += T p'), and the play
operator (seed eqs 6-8, c = half the play) updates s. It is first order in T.

A run is advanced in chunks of steps, one compiled call each (:func:`integrate`), so that
Ctrl-C and SIGTERM, which Python acts on only between calls, end a long run within about
:data:`CHUNK_S`. A chunk carries the loop's counters and running figures to the next one
(``carry``, slots ``C_*``) and every step's time is ``t0 + step * dt`` with the run's own step
index, so a run in chunks gives the same numbers, bit for bit, as one call.

The loop compiles in :func:`kernel.rhs` and everything it calls (layout constants, the cam
kernels); the compiled-code cache is keyed on a hash of all those sources
(:mod:`servo_toolkit.core.jit_cache`), so editing any of them recompiles the loop.
"""

from __future__ import annotations

import math
import time

import numba as nb
import numpy as np

from .kernel import FASTMATH, controller_sample, inline, jit, reference, rhs, rhs_phys
from .node_switch import node_flags
from .split_step import rk4_coefficients, stage_turns, switch_ahead
from .switch_loop import switched_step
from .tables import frozen_tables
from .layout import (AUX_I, AUX_IREF, AUX_TAU, AUX_V, CMODE, CONTINUOUS, F_CUR, F_ERR, F_SAT, F_STATUS,
                     F_STEP, F_TAU, HALF_PLAY, ILIM, NAUX, NFIG, NMID, NODE_FRIC, NSNAP, NONFINITE, NX_PHYS, OK, S_DEFLECTION, S_END,
                     S_PEAK, STICK, TS_M, TS_L, RIGID, STROKE_END, STROKE_HI, STROKE_LO, STROKE_MODE, VLIM)


#: the fixed-step loop's compilation: without the runtime's reference counting, whose atomic
#: increments and decrements (of the arrays bound by every inlined helper, at every step) took
#: most of a step's time; the loop allocates nothing (:func:`scratch` is its caller's)
loop_jit = nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)


#: wall time (s) a chunk of a long run aims at: an interrupt waits about this long
CHUNK_S = 0.2
#: steps of a run's first chunk (later ones scale to :data:`CHUNK_S` by the time it took)
FIRST_CHUNK = 2000
#: the loops' state carried from one chunk to the next: held current reference, steps to the
#: next controller sample and to the next record, records written, peak |motor torque|, and
#: RK4's running figures (peak |tracking error|, |current|, deflection, a limit reached)
C_IREF, C_TO_SAMPLE, C_TO_RECORD, C_NREC, C_MAX_TAU, C_MAX_ERR, C_MAX_CUR, C_MAX_DEFL, C_SAT = range(9)
NCARRY = 9


@jit
def _finite(x):
    """One test per step: a NaN or inf anywhere makes the sum non-finite."""
    acc = 0.0
    for j in range(x.size):
        acc += x[j]
    return math.isfinite(acc)


def integrate(x, P, T, t0, dt, n_steps, sub, iref, paper, rec_every, out_t, out_x, out_aux, fig=None, snap=None,
              chunk=None):
    """Advance ``x`` in place by ``n_steps`` fixed steps.

    RK4 also fills ``fig`` (``NFIG``: the figures kept at every step, ``F_*`` of
    :mod:`.layout`) and ``snap`` (``(NSNAP, nx + 2)`` snapshots, ``S_*``) when given; the
    paper's scheme leaves them as they are. The steps run in chunks, one compiled call each,
    so that a KeyboardInterrupt (Ctrl-C, or SIGTERM turned into one) raised between two
    calls ends a long run; the numbers do not depend on the chunks.

    Parameters
    ----------
    chunk : int, optional
        Steps per compiled call; default: :data:`FIRST_CHUNK`, then as many as take about
        :data:`CHUNK_S` at the speed measured so far.

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

    Notes
    -----
    The choice between the loops is made here, in Python, so that a run compiles only the
    loop it uses.
    """
    T = frozen_tables(T)
    n_steps = int(n_steps)
    carry = np.zeros(NCARRY)
    if paper:
        def advance(first, last):
            return _paper(x, P, T, float(t0), float(dt), first, last, n_steps, int(sub), float(iref), True,
                          int(rec_every), out_t, out_x, out_aux, carry)
    else:
        if fig is None:
            fig = np.zeros(NFIG)
        if snap is None:
            snap = np.zeros((NSNAP, x.size + 2))
        work = scratch(x.size, P.size)

        def advance(first, last):
            return _rk4(x, P, T, float(t0), float(dt), first, last, n_steps, int(sub), float(iref),
                        int(rec_every), out_t, out_x, out_aux, fig, snap, carry, *work)
    first, size = 0, max(1, int(chunk or FIRST_CHUNK))
    while True:
        last = min(first + size, n_steps)
        start = time.perf_counter()
        result = advance(first, last)
        if result[0] != OK or last >= n_steps:
            return result
        if chunk is None:  # as many steps as take about CHUNK_S, growing at most tenfold a call
            spent = max(time.perf_counter() - start, 1e-9)
            size = max(FIRST_CHUNK, min(10 * size, int(size * CHUNK_S / spent)))
        first = last


def scratch(nx: int, n_par: int):
    """The scratch arrays of :func:`_rk4` for nx states and n_par parameters: the stages'
    slopes and state (zeros), the controller's work vector and the split step's state and
    parameter copies (4 rows, each wide enough for P and for x)."""
    return np.zeros((5, nx)), np.empty(max(nx, 1)), np.empty(nx), np.empty((4, max(n_par, nx)))


@inline
def sample_hold(t, sub, to_sample, iref, p, pd, q, qd, cur, xi, s, x, P, T, work):
    """The zero-order hold of the sampled controller: every ``sub`` steps (none when 0) the
    physical state is written to x[0:7] and the controller sampled. Returns the held i_ref
    and the steps left to the next sample."""
    if sub > 0:
        if to_sample == 0:
            x[0], x[1], x[2], x[3], x[4], x[5], x[6] = p, pd, q, qd, cur, xi, s
            iref = controller_sample(t, x, P, T, work)
            to_sample = sub
        to_sample -= 1
    return iref, to_sample


@inline
def step_status(p, pd, q, qd, cur, xi, s, x, tau, P, err_mode, rigid):
    """OK, NONFINITE (one test: a NaN or inf anywhere makes the sum non-finite) or
    STROKE_END (``err_mode``: the output left the stroke)."""
    acc = p + pd + q + qd + cur + xi + s
    for j in range(NX_PHYS, x.size):
        acc += x[j]
    if not math.isfinite(acc) or not math.isfinite(tau):
        return NONFINITE
    qo = p if rigid else q
    if err_mode and (qo > P[STROKE_HI] or qo < P[STROKE_LO]):
        return STROKE_END
    return OK


@jit
def snapshot(snap, k, p, pd, q, qd, cur, xi, s, x, t, iref):
    """Row ``k`` of a run's snapshots: the physical state, x[7:], the time and the held i_ref."""
    nx = x.size
    snap[k, 0], snap[k, 1], snap[k, 2], snap[k, 3] = p, pd, q, qd
    snap[k, 4], snap[k, 5], snap[k, 6] = cur, xi, s
    for j in range(NX_PHYS, nx):
        snap[k, j] = x[j]
    snap[k, nx] = t
    snap[k, nx + 1] = iref


@loop_jit
def _rk4(x, P, T, t0, dt, first, last, n_steps, sub, iref, rec_every, out_t, out_x, out_aux, fig, snap, carry, K, work,
         x0, PW):
    """Classical RK4 with the physical states x[0:7] held in local scalars (registers).

    Same arithmetic as the array form (:func:`kernel.rhs`); x[0:7] is written back before
    each controller sample and at the end. The controller and estimator states x[7:] change
    only at the samples unless the motion controller is continuous. Every ``rec_every``
    steps the state at the step's start is recorded; at every step the run's figures
    (``fig``, ``F_*`` of :mod:`.layout`: peak tracking error, current and torque, limits
    reached) and its snapshots (``snap``, ``S_*``) are kept, so that a figure never depends
    on the record interval.

    The call runs the steps ``first`` .. ``last - 1`` of a run of ``n_steps`` (and its end,
    the record and the check at ``n_steps``, when ``last`` is ``n_steps``); ``carry`` (slots
    ``C_*``) takes the loop's counters and running figures from the call before it (none when
    ``first`` is 0: ``iref`` is then the held current reference) and keeps them for the next.
    """
    nx = x.size
    k1, k2, k3, k4, xs = K[0], K[1], K[2], K[3], K[4]  # the stages' slopes and state: zeros
    n_rec = 0
    max_tau = 0.0
    max_err = 0.0
    max_cur = -1.0
    max_defl = -1.0
    sat = 0.0
    to_sample = 0
    to_record = 0
    if first > 0:
        iref, to_sample, to_record = carry[C_IREF], int(carry[C_TO_SAMPLE]), int(carry[C_TO_RECORD])
        n_rec, max_tau, max_err = int(carry[C_NREC]), carry[C_MAX_TAU], carry[C_MAX_ERR]
        max_cur, max_defl, sat = carry[C_MAX_CUR], carry[C_MAX_DEFL], carry[C_SAT]
    stop = n_steps + 1 if last >= n_steps else last
    ilim = P[ILIM]
    vlim = P[VLIM]
    err_mode = P[STROKE_MODE] == 0.0
    rigid = P[RIGID] > 0.0
    # states in x[7:] that move between samples: a continuous controller's, the full chain's nodes
    cont = int(P[CMODE]) == CONTINUOUS or P[NMID] > 0.0
    stick = P[STICK] > 0.0  # friction that holds: speed reversals are located within the step
    lands = stick and P[NODE_FRIC] > 0.0  # ... at the full chain's intermediate nodes too
    p, pd, q, qd, cur, xi, s = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
    status = OK
    sixth = dt / 6.0
    g1 = g3 = 0.0
    step = first
    t = t0 + first * dt
    for step in range(first, stop):
        t = t0 + step * dt
        iref, to_sample = sample_hold(t, sub, to_sample, iref, p, pd, q, qd, cur, xi, s, x, P, T, work)
        err = abs(q - reference(t, P))
        if err > max_err:
            max_err = err
        # the four stages share one inlined right-hand side (one copy compiles in a quarter
        # of the time of four); stage k evaluates at t + c_k dt from the previous slopes and
        # enters the update with weight w_k; the first stage also records and checks
        s0 = s1 = s2 = s3 = s4 = s5 = 0.0
        u0 = u1 = u2 = u3 = u4 = u5 = 0.0
        done = False
        turned = False  # a stage's speed left a node's direction (friction that holds)
        for stage in range(4):
            c, w = rk4_coefficients(stage, dt)
            kout = k1 if stage == 0 else (k2 if stage == 1 else (k3 if stage == 2 else k4))
            if cont and stage > 0:
                kin = k1 if stage == 1 else (k2 if stage == 2 else k3)
                for j in range(NX_PHYS, nx):
                    xs[j] = x[j] + c * kin[j]
            if stick and stage > 0:
                turned = turned or stage_turns(pd, pd + c * s1, qd, qd + c * s3)
            s0, s1, s2, s3, s4, s5, i_, v_, r_, tau_ = rhs_phys(
                t + c, p + c * s0, pd + c * s1, q + c * s2, qd + c * s3, cur + c * s4, xi + c * s5, s,
                P, T, iref, x if stage == 0 else xs, kout, False, True)
            if stage == 0:
                g1, g3 = s1, s3  # the slopes at the step's start (speed reversals)
                tau = abs(tau_)
                if tau > max_tau:
                    max_tau = tau
                if abs(r_) >= ilim or abs(v_) >= vlim:
                    sat = 1.0
                if abs(i_) > max_cur:
                    max_cur = abs(i_)
                    snapshot(snap, S_PEAK, p, pd, q, qd, i_, xi, s, x, t, iref)
                defl = abs(p - q)
                if defl > max_defl:
                    max_defl = defl
                    snapshot(snap, S_DEFLECTION, p, pd, q, qd, cur, xi, s, x, t, iref)
                if to_record == 0 or step == n_steps:
                    to_record = rec_every
                    out_t[n_rec] = t
                    out_x[n_rec, 0] = p
                    out_x[n_rec, 1] = pd
                    out_x[n_rec, 2] = q
                    out_x[n_rec, 3] = qd
                    out_x[n_rec, 4] = cur
                    out_x[n_rec, 5] = xi
                    out_x[n_rec, 6] = s
                    for j in range(NX_PHYS, nx):
                        out_x[n_rec, j] = x[j]
                    out_aux[n_rec, AUX_I] = i_
                    out_aux[n_rec, AUX_V] = v_
                    out_aux[n_rec, AUX_IREF] = r_
                    out_aux[n_rec, AUX_TAU] = tau_
                    n_rec += 1
                to_record -= 1
                status = step_status(p, pd, q, qd, cur, xi, s, x, tau, P, err_mode, rigid)
                if status != OK or step == n_steps:
                    done = True
                    break
            u0 += w * s0
            u1 += w * s1
            u2 += w * s2
            u3 += w * s3
            u4 += w * s4
            u5 += w * s5
        if done:
            break
        if stick:
            # a node carrying friction may reverse or break away within the step (the motor side
            # or the load: ends; the full chain's intermediate nodes: mask): split it there
            ends = turned or switch_ahead(pd, pd + sixth * u1, pd + dt * g1, qd, qd + sixth * u3, qd + dt * g3,
                                          P, rigid)
            mask = node_flags(x, k1, k2, k3, k4, sixth, P) if lands else 0
            if ends or mask:
                p, pd, q, qd, cur, xi = switched_step(t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x,
                                                      xs, k1, k2, k3, k4, pd + sixth * u1, qd + sixth * u3, x0, PW,
                                                      ends, mask)
                continue
        if cont:
            for j in range(NX_PHYS, nx):
                x[j] += sixth * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        p, pd, q, qd, cur, xi = (p + sixth * u0, pd + sixth * u1, q + sixth * u2, qd + sixth * u3,
                                 cur + sixth * u4, xi + sixth * u5)
    x[0], x[1], x[2], x[3], x[4], x[5], x[6] = p, pd, q, qd, cur, xi, s
    snapshot(snap, S_END, p, pd, q, qd, cur, xi, s, x, t, iref)
    carry[C_IREF], carry[C_TO_SAMPLE], carry[C_TO_RECORD] = iref, to_sample, to_record
    carry[C_NREC], carry[C_MAX_TAU], carry[C_MAX_ERR] = n_rec, max_tau, max_err
    carry[C_MAX_CUR], carry[C_MAX_DEFL], carry[C_SAT] = max_cur, max_defl, sat
    done_steps = min(last, n_steps)
    fig[F_STATUS] = status
    fig[F_STEP] = step if status != OK else done_steps
    fig[F_ERR] = max_err
    fig[F_CUR] = max_cur
    fig[F_SAT] = sat
    fig[F_TAU] = max_tau
    if status != OK:
        return status, step, n_rec, max_tau, iref
    return OK, done_steps, n_rec, max_tau, iref


@jit
def _paper(x, P, T, t0, dt, first, last, n_steps, sub, iref, paper, rec_every, out_t, out_x, out_aux, carry):
    """The cam paper's scheme (and the array form of RK4 when ``paper`` is False), steps
    ``first`` .. ``last - 1`` of ``n_steps`` with ``carry`` as :func:`_rk4` takes them."""
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
    if first > 0:
        iref, to_sample, to_record = carry[C_IREF], int(carry[C_TO_SAMPLE]), int(carry[C_TO_RECORD])
        n_rec, max_tau = int(carry[C_NREC]), carry[C_MAX_TAU]
    stop = n_steps + 1 if last >= n_steps else last
    for step in range(first, stop):
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
        for stage in range(3):  # stages 2-4 in one loop (see _rk4)
            h = dt if stage == 2 else half
            kin = k1 if stage == 0 else (k2 if stage == 1 else k3)
            kout = k2 if stage == 0 else (k3 if stage == 1 else k4)
            if paper:  # frozen configuration: no position slope enters the later stages
                kin[0] = 0.0
                kin[2] = 0.0
                kin[6] = 0.0
            for j in range(nx):
                xs[j] = x[j] + h * kin[j]
            rhs(t + h, xs, P, T, iref, kout, aux2)
        p_old = x[0]
        q_old = x[2]
        p_speed = x[1]
        for j in range(nx):
            x[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        if P[STICK] > 0.0 and x[1] * p_speed < 0.0 and (P[TS_M] > 0.0 or P[TS_L] > 0.0):
            # friction that holds, in the fixed-configuration scheme: a speed reversal ends the
            # step at rest (Karnopp), where the friction decides between stick and slip
            x[1] = 0.0
            if qi == 0:
                x[3] = 0.0
        if paper:  # positions by summation from the new velocities (the RK4 sum above moved them)
            x[0] = p_old + dt * x[1]
            x[2] = q_old + dt * x[3]
            p = x[0]
            if p > p_old and p > x[6] + c:
                x[6] = p - c
            elif p < p_old and p < x[6] - c:
                x[6] = p + c
    carry[C_IREF], carry[C_TO_SAMPLE], carry[C_TO_RECORD] = iref, to_sample, to_record
    carry[C_NREC], carry[C_MAX_TAU] = n_rec, max_tau
    return OK, min(last, n_steps), n_rec, max_tau, iref
