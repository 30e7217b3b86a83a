# batch.h: many closed-loop variants, each the single run's RK4 loop, shared among worker threads
# that run without the interpreter lock (a variant's numbers do not depend on its thread).
import itertools as _itertools
from concurrent.futures import ThreadPoolExecutor as _ThreadPoolExecutor

import numpy as np
from libc.stdint cimport int64_t

cdef extern from "api_batch.h":
    long st_batch_nfig() nogil
    long st_batch_nsnap() nogil
    long st_batch_naux() nogil
    int st_variant_run(double *x, long nx, const double *P, long n_par, Tab T, double dt, long n_steps, long sub,
                       double *fig, double *snap) nogil
    int st_variant_share(double *X, long nx, const double *P, long n_par, const double *T3, long t_rows, long t_n,
                         const int64_t *tix, double dt, long n_steps, long sub, double *figs, double *snaps,
                         long v0, long v1) nogil
    void st_jacobians(const double *X, long n_rows, long n_states, const double *times, const double *irefs,
                      const double *P, long n_par, const double *T3, long t_rows, long t_n, const int64_t *tix,
                      const int64_t *vix, double *out, double *scratch) nogil


def variant_run(double[::1] x, const double[::1] P, const double[:, ::1] T, double dt, long n_steps, long sub,
                double[::1] fig, double[:, ::1] snap):
    """One variant: the single run's RK4 loop, keeping its figures and snapshots.

    ``x`` is advanced in place; ``fig`` (NFIG) receives status (layout.OK, NONFINITE,
    STROKE_END), steps done, max |q - r|, max |i|, 1 if the current reference or the voltage
    reached its limit, max |motor torque|; ``snap`` (NSNAP, nx + 2) the states of S_PEAK,
    S_DEFLECTION and S_END with their time and held current reference. Runs without the
    interpreter lock."""
    cdef long nx = x.shape[0]
    if nx < 1 or P.shape[0] < 1 or T.shape[0] < 1 or T.shape[1] < 1:
        raise ValueError("variant_run: empty state, parameters or tables")
    if fig.shape[0] < st_batch_nfig() or snap.shape[0] < st_batch_nsnap() or snap.shape[1] != nx + 2:
        raise ValueError(f"variant_run: fig needs {st_batch_nfig()} slots and snap "
                         f"({st_batch_nsnap()}, {nx + 2}) (got {fig.shape[0]}, ({snap.shape[0]}, {snap.shape[1]}))")
    if n_steps < 0 or sub < 0:
        raise ValueError("variant_run: n_steps and sub must be >= 0")
    cdef int rc
    cdef Tab tab = tab_of(T)
    with nogil:
        rc = st_variant_run(&x[0], nx, &P[0], P.shape[0], tab, dt, n_steps, sub, &fig[0], &snap[0, 0])
    if rc != 0:
        raise MemoryError("variant_run: no memory for the run's scratch")


def _variant_share(double[:, ::1] X, const double[:, ::1] P, const double[:, :, ::1] T, const int64_t[::1] tix,
                   double dt, long n_steps, long sub, double[:, ::1] figs, double[:, :, ::1] snaps, long v0, long v1):
    """variant_run for the variants v0 .. v1 - 1 (checked by the caller), without the lock."""
    cdef int rc
    if v1 <= v0:
        return
    with nogil:
        rc = st_variant_share(&X[0, 0], X.shape[1], &P[0, 0], P.shape[1], &T[0, 0, 0], T.shape[1], T.shape[2],
                              &tix[0], dt, n_steps, sub, &figs[0, 0], &snaps[0, 0, 0], v0, v1)
    if rc != 0:
        raise MemoryError("run_variants: no memory for a run's scratch")


def _written(a, name, shape):
    """``a`` as it is written in place: float64, C-contiguous, of ``shape``."""
    if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable):
        raise ValueError(f"run_variants: {name} must be a writeable C-contiguous float64 array")
    if a.shape != shape:
        raise ValueError(f"run_variants: {name} has shape {a.shape}, not {shape}")
    return a


def run_variants(X, P, T, tix, dt, n_steps, sub, figs, snaps, threads=1):
    """:func:`variant_run` for every row of ``X`` (states, advanced in place) and ``P``, with
    tables ``T[tix[v]]``, into ``figs[v]`` and ``snaps[v]``, on ``threads`` worker threads
    (each takes the next variant not yet run, without the interpreter lock; a variant's
    numbers do not depend on the thread that ran it).

    Parameters
    ----------
    X : numpy.ndarray
        (n_variants, nx) float64, C-contiguous: the starts, advanced in place.
    P : numpy.ndarray
        (n_variants, nP) parameters.
    T : numpy.ndarray
        (n_tables, rows, points) stroke tables.
    tix : numpy.ndarray
        (n_variants,) integer table index of each variant.
    dt : float
    n_steps, sub : int
        Steps, steps per controller sample (0: continuous).
    figs, snaps : numpy.ndarray
        (n_variants, NFIG) and (n_variants, NSNAP, nx + 2) float64, C-contiguous: written.
    threads : int
        Worker threads (1: the calling thread, without the lock).
    """
    X = _written(X, "X", np.shape(X))
    if X.ndim != 2:
        raise ValueError("run_variants: X must be (n_variants, nx)")
    nv, nx = X.shape
    P = np.ascontiguousarray(P, dtype=np.float64)
    T = np.ascontiguousarray(T, dtype=np.float64)
    tix = np.ascontiguousarray(tix, dtype=np.int64)
    if P.ndim != 2 or P.shape[0] != nv or T.ndim != 3 or tix.shape != (nv,):
        raise ValueError(f"run_variants: P must be ({nv}, nP), T (n_tables, rows, points) and tix ({nv},)")
    figs = _written(figs, "figs", (nv, st_batch_nfig()))
    snaps = _written(snaps, "snaps", (nv, st_batch_nsnap(), nx + 2))
    if nv == 0:
        return
    if nx < 1 or P.shape[1] < 1 or T.shape[1] < 1 or T.shape[2] < 1:
        raise ValueError("run_variants: empty states, parameters or tables")
    if tix.min() < 0 or tix.max() >= T.shape[0]:
        raise ValueError(f"run_variants: a table index outside 0 .. {T.shape[0] - 1}")
    dt, n_steps, sub = float(dt), int(n_steps), int(sub)
    if n_steps < 0 or sub < 0:
        raise ValueError("run_variants: n_steps and sub must be >= 0")
    threads = max(1, min(int(threads), nv))
    if threads == 1:
        _variant_share(X, P, T, tix, dt, n_steps, sub, figs, snaps, 0, nv)
        return
    counter = _itertools.count()  # next() on it is atomic under the interpreter lock

    def worker():
        while True:
            v = next(counter)
            if v >= nv:
                return
            _variant_share(X, P, T, tix, dt, n_steps, sub, figs, snaps, v, v + 1)

    with _ThreadPoolExecutor(threads) as pool:
        for job in [pool.submit(worker) for _ in range(threads)]:
            job.result()


def jacobians(X, times, irefs, P, T, tix, vix, out):
    """d(rhs)/dx by central differences (steps as :func:`servo_toolkit.sim.stability.jacobian`)
    at the states ``X[m]`` of variants ``vix[m]`` (time ``times[m]``, held current reference
    ``irefs[m]``, parameters ``P[vix[m]]``, tables ``T[tix[vix[m]]]``), into ``out[m]``
    ((n_rows, nx, nx) float64, C-contiguous)."""
    X = np.ascontiguousarray(X, dtype=np.float64)
    times = np.ascontiguousarray(times, dtype=np.float64)
    irefs = np.ascontiguousarray(irefs, dtype=np.float64)
    P = np.ascontiguousarray(P, dtype=np.float64)
    T = np.ascontiguousarray(T, dtype=np.float64)
    tix = np.ascontiguousarray(tix, dtype=np.int64)
    vix = np.ascontiguousarray(vix, dtype=np.int64)
    if X.ndim != 2:
        raise ValueError("jacobians: X must be (n_rows, nx)")
    m, n = X.shape
    out = _written(out, "out", (m, n, n))
    if times.shape != (m,) or irefs.shape != (m,) or vix.shape != (m,):
        raise ValueError(f"jacobians: times, irefs and vix must be ({m},)")
    if P.ndim != 2 or T.ndim != 3 or tix.ndim != 1 or tix.shape[0] != P.shape[0]:
        raise ValueError("jacobians: P must be (n_variants, nP), T (n_tables, rows, points), tix (n_variants,)")
    if m == 0 or n == 0:
        return
    if vix.min() < 0 or vix.max() >= P.shape[0]:
        raise ValueError(f"jacobians: a variant index outside 0 .. {P.shape[0] - 1}")
    used = tix[vix]
    if used.min() < 0 or used.max() >= T.shape[0]:
        raise ValueError(f"jacobians: a table index outside 0 .. {T.shape[0] - 1}")
    _jacobians(X, times, irefs, P, T, tix, vix, out)


def _jacobians(const double[:, ::1] X, const double[::1] times, const double[::1] irefs, const double[:, ::1] P,
               const double[:, :, ::1] T, const int64_t[::1] tix, const int64_t[::1] vix, double[:, :, ::1] out):
    cdef long n = X.shape[1]
    cdef double[::1] scratch = np.empty(4 * n + st_batch_naux())
    with nogil:
        st_jacobians(&X[0, 0], X.shape[0], n, &times[0], &irefs[0], &P[0, 0], P.shape[1], &T[0, 0, 0], T.shape[1],
                     T.shape[2], &tix[0], &vix[0], &out[0, 0, 0], &scratch[0])
