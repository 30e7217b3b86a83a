"""Many closed-loop variants timed: the compiled batch (:mod:`.batch`) on worker threads,
in calls that each take about :data:`~.integrators.CHUNK_S` (Ctrl-C and SIGTERM are honoured
between two calls; a variant's numbers depend neither on the calls nor on the threads)."""

from __future__ import annotations

import os
import time

import numpy as np

from .batch import run_variants
from .integrators import CHUNK_S
from .layout import NFIG, NSNAP
from .tables import frozen_tables


def worker_threads() -> int:
    """Threads a batch runs on: the processors this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # macOS, Windows
        return max(1, os.cpu_count() or 1)


def integrate_variants(P, T, tix, X0, dt: float, n_steps: int, sub: int, threads: int | None = None):
    """Run the variants (:func:`.batch.run_variants`) on ``threads`` worker threads.

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
    threads : int, optional
        Worker threads; default :func:`worker_threads`.

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
    T = frozen_tables(T)
    tix = np.ascontiguousarray(tix, dtype=np.int64)
    X = np.array(X0, dtype=float, order="C")
    nv, nx = X.shape
    figs = np.zeros((nv, NFIG))
    snaps = np.zeros((nv, NSNAP, nx + 2))
    threads = int(threads or worker_threads())
    start = time.perf_counter()
    v, size = 0, threads  # first call: one variant per thread; then as many as take about CHUNK_S
    while v < nv:
        end = min(nv, v + size)
        began = time.perf_counter()
        run_variants(X[v:end], P[v:end], T, tix[v:end], float(dt), int(n_steps), int(sub), figs[v:end],
                     snaps[v:end], threads)
        per_variant = max(time.perf_counter() - began, 1e-9) / (end - v)
        size = max(threads, min(10 * (end - v), int(CHUNK_S * threads / per_variant)))
        v = end
    return X, figs, snaps, time.perf_counter() - start
