"""Many closed-loop variants in one call: the SIMD lanes of :mod:`.batch_lanes` (which equal
the per-variant loop of :mod:`.batch`), timed after their machine code is loaded."""

from __future__ import annotations

import time

import numpy as np

from .batch import NFIG, NSNAP
from .batch_lanes import run_lanes
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
    run_lanes(X, P, T, tix, dt, int(n_steps), int(sub), figs, snaps)
    return X, figs, snaps, time.perf_counter() - start
