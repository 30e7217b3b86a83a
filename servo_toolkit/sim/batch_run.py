"""Many closed-loop variants: the SIMD lanes of :mod:`.batch_lanes` (which equal the
per-variant loop of :mod:`.batch`), timed after their machine code is loaded, in calls of
whole blocks of variants that each take about :data:`~.integrators.CHUNK_S` (Ctrl-C and
SIGTERM are honoured between two calls; a variant's numbers do not depend on them)."""

from __future__ import annotations

import math
import time

import numba as nb
import numpy as np

from .batch import NFIG, NSNAP
from .batch_lanes import W, run_lanes
from .integrators import CHUNK_S
from .tables import frozen_tables


def integrate_variants(P, T, tix, X0, dt: float, n_steps: int, sub: int):
    """Run the variants in SIMD lanes (:func:`.batch_lanes.run_lanes`, which equals
    :func:`.batch.run_variants`); compilation is done before the clock starts.

    Parameters
    ----------
    P : numpy.ndarray
        (n_variants, nP) parameters, reference slots filled.
    T : numpy.ndarray
        (n_tables, rows, points) stroke tables.
    tix : numpy.ndarray
        (n_variants,) table index of each variant.
    X0 : numpy.ndarray
        (n_variants, nx) initial states (copied).
    dt : float
    n_steps : int
    sub : int
        Steps per controller sample (0: continuous).

    Returns
    -------
    X : numpy.ndarray
        Final states.
    figs : numpy.ndarray
        (n_variants, NFIG), columns ``F_*``.
    snaps : numpy.ndarray
        (n_variants, NSNAP, nx + 2).
    wall : float
        Seconds of integration.
    """
    P = np.ascontiguousarray(P, dtype=float)
    # read-only, as a single run's tables are: the per-variant kernels then share the single
    # run's compiled right-hand side and controller sample instead of compiling their own
    T = frozen_tables(T)
    tix = np.ascontiguousarray(tix, dtype=np.int64)
    X = np.array(X0, dtype=float, order="C")
    nv, nx = X.shape
    figs = np.zeros((nv, NFIG))
    snaps = np.zeros((nv, NSNAP, nx + 2))
    # warm-up: a zero-step call loads (or compiles) the machine code before the clock starts
    run_lanes(X[:1].copy(), P[:1], T, tix[:1], dt, 0, sub, figs[:1].copy(), snaps[:1].copy())
    start = time.perf_counter()
    threads = nb.get_num_threads()
    v, blocks = 0, threads  # first call: one block per thread; then rounds of that within CHUNK_S
    while v < nv:
        end = min(nv, v + blocks * W)  # whole blocks: each variant meets the block-mates of one call
        began = time.perf_counter()
        run_lanes(X[v:end], P[v:end], T, tix[v:end], dt, int(n_steps), int(sub), figs[v:end], snaps[v:end])
        rounds = math.ceil((end - v) / W / threads)
        per_round = max(time.perf_counter() - began, 1e-9) / rounds
        blocks = threads * max(1, min(10 * rounds, int(CHUNK_S / per_round)))
        v = end
    return X, figs, snaps, time.perf_counter() - start
