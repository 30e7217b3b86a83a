"""Fixed-step loops: classical RK4 and the cam paper's discrete scheme (seed 002), compiled.

Both loops (``servo_toolkit/_physics/integrate.h``) hold the sampled controller's output
between samples (zero-order hold), sample it every ``sub`` steps, record every ``rec_every``
steps, track the peak motor torque at every step, and stop with a status code on a
non-finite state or on the stroke end. No allocation happens inside the loop; the loop runs
without the interpreter lock.

RK4 keeps the physical state in registers, with the right-hand side inlined into it, and
splits a step where friction that holds switches within it: a speed reversal or a breakaway
of the motor side, the load or a node of the full chain, located by the Illinois method to
``TAU_TOL`` of the step (``split_step.h``, ``switch_loop.h`` and ``node_switch.h`` in
``servo_toolkit/_physics``).

The paper's scheme (seed 002 section 3): over each step the configuration (p, q, the play
state s) is frozen, the velocities and electrical states take one RK4 step with J(p), N(p)
and the spring moment frozen, positions follow by summation (p += T p'), and the play
operator (seed eqs 6-8, c = half the play) updates s. It is first order in T.

A run is advanced in chunks of steps, one compiled call each (:func:`integrate`), so that
Ctrl-C and SIGTERM, which Python acts on only between calls, end a long run within about
:data:`CHUNK_S`. A chunk carries the loop's counters and running figures to the next one
(``carry``, slots ``C_*`` of :mod:`.layout`) and every step's time is ``t0 + step * dt`` with
the run's own step index, so a run in chunks gives the same numbers, bit for bit, as one call.
"""

from __future__ import annotations

import time

import numpy as np

from .._physics._kernels import paper as _paper, rk4 as _rk4  # noqa: F401 - the loops, one call each
from .layout import (C_IREF, C_MAX_CUR, C_MAX_DEFL, C_MAX_ERR, C_MAX_TAU, C_NREC, C_SAT,  # noqa: F401
                     C_TO_RECORD, C_TO_SAMPLE, NCARRY, NFIG, NSNAP, OK)
from .tables import frozen_tables

#: wall time (s) a chunk of a long run aims at: an interrupt waits about this long
CHUNK_S = 0.2
#: steps of a run's first chunk (later ones scale to :data:`CHUNK_S` by the time it took)
FIRST_CHUNK = 2000


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
