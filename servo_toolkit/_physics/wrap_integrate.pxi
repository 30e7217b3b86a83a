# The fixed-step loops (integrate.h): classical RK4 and the paper's scheme, one chunk of a run per
# call, the whole chunk without the GIL.
from libc.stdlib cimport malloc, free

cdef extern from "api_integrate.h":
    void st_integrate_dims(long dims[4]) nogil
    void st_rk4(double *x, long nx, const double *P, long n_par, Tab T, double t0, double dt, long first,
                long last, long n_steps, long sub, double iref, long rec_every, double *out_t, double *out_x,
                double *out_aux, double *fig, double *snap, double *carry, double *K, double *work, double *x0,
                double *PW, long pw_stride, long *status, long *step, long *n_rec, double *max_tau,
                double *iref_out) nogil
    void st_paper(double *x, long nx, const double *P, Tab T, double t0, double dt, long first, long last,
                  long n_steps, long sub, double iref, int paper_scheme, long rec_every, double *out_t,
                  double *out_x, double *out_aux, double *carry, double *scratch, long *status, long *step,
                  long *n_rec, double *max_tau, double *iref_out) nogil


cdef long _DIMS[4]
st_integrate_dims(_DIMS)
cdef long _NFIG = _DIMS[0], _NSNAP = _DIMS[1], _NAUX = _DIMS[2], _NCARRY = _DIMS[3]


cdef inline int _need(bint ok, str what) except -1:
    if not ok:
        raise ValueError(f"integrate loop: {what}")
    return 0


cdef inline int _check_records(long nx, const double[::1] out_t, double[:, ::1] out_x,
                               double[:, ::1] out_aux) except -1:
    _need(out_x.shape[1] == nx, f"out_x has {out_x.shape[1]} columns, x has {nx} states")
    _need(out_aux.shape[1] == _NAUX, f"out_aux needs {_NAUX} columns")
    _need(out_t.shape[0] >= 1 and out_x.shape[0] >= 1 and out_aux.shape[0] >= 1,
          "out_t, out_x and out_aux need a row at least")
    return 0


def rk4(double[::1] x, const double[::1] P, const double[:, ::1] T, double t0, double dt, long first, long last,
        long n_steps, long sub, double iref, long rec_every, double[::1] out_t, double[:, ::1] out_x,
        double[:, ::1] out_aux, double[::1] fig, double[:, ::1] snap, double[::1] carry, double[:, ::1] K,
        double[::1] work, double[::1] x0, double[:, ::1] PW):
    """Classical RK4, steps ``first`` .. ``last - 1`` of a run of ``n_steps`` (and the end's record
    and check when ``last >= n_steps``), as ``servo_toolkit.sim.integrators._rk4`` takes its
    arguments (``K, work, x0, PW`` from ``integrators.scratch``; ``PW``'s rows are written: the split
    step's parameter copies). Returns ``(status, step, n_rec, max_tau, iref)``."""
    cdef long nx = x.shape[0], n_par = P.shape[0]
    cdef long status, step, n_rec
    cdef double max_tau, iref_out
    _need(nx >= 7, "x needs the 7 physical states")
    _check_records(nx, out_t, out_x, out_aux)
    _need(fig.shape[0] >= _NFIG, f"fig needs {_NFIG} values")
    _need(snap.shape[0] >= _NSNAP and snap.shape[1] == nx + 2, f"snap needs ({_NSNAP}, nx + 2)")
    _need(carry.shape[0] >= _NCARRY, f"carry needs {_NCARRY} values")
    _need(K.shape[0] >= 5 and K.shape[1] == nx, "K needs (5, nx)")
    _need(work.shape[0] >= nx and x0.shape[0] >= nx, "work and x0 need nx values")
    _need(PW.shape[0] >= 4 and PW.shape[1] >= n_par and PW.shape[1] >= nx, "PW needs (4, max(P.size, nx))")
    _need(rec_every >= 1, "rec_every must be at least 1")
    cdef Tab tab = tab_of(T)
    with nogil:
        st_rk4(&x[0], nx, &P[0], n_par, tab, t0, dt, first, last, n_steps, sub, iref, rec_every, &out_t[0],
               &out_x[0, 0], &out_aux[0, 0], &fig[0], &snap[0, 0], &carry[0], &K[0, 0], &work[0], &x0[0],
               &PW[0, 0], PW.shape[1], &status, &step, &n_rec, &max_tau, &iref_out)
    return status, step, n_rec, max_tau, iref_out


def paper(double[::1] x, const double[::1] P, const double[:, ::1] T, double t0, double dt, long first, long last,
          long n_steps, long sub, double iref, bint paper, long rec_every, double[::1] out_t,
          double[:, ::1] out_x, double[:, ::1] out_aux, double[::1] carry):
    """The cam paper's scheme (RK4's array form when ``paper`` is False), steps ``first`` ..
    ``last - 1`` of ``n_steps``, as ``servo_toolkit.sim.integrators._paper`` takes its arguments.
    Returns ``(status, step, n_rec, max_tau, iref)``."""
    cdef long nx = x.shape[0]
    cdef long status, step, n_rec
    cdef double max_tau, iref_out
    _need(nx >= 7, "x needs the 7 physical states")
    _check_records(nx, out_t, out_x, out_aux)
    _need(carry.shape[0] >= _NCARRY, f"carry needs {_NCARRY} values")
    _need(rec_every >= 1, "rec_every must be at least 1")
    cdef Tab tab = tab_of(T)
    cdef double *scratch = <double *>malloc((5 * nx + nx) * sizeof(double))
    if scratch == NULL:
        raise MemoryError()
    try:
        with nogil:
            st_paper(&x[0], nx, &P[0], tab, t0, dt, first, last, n_steps, sub, iref, paper, rec_every, &out_t[0],
                     &out_x[0, 0], &out_aux[0, 0], &carry[0], scratch, &status, &step, &n_rec, &max_tau, &iref_out)
    finally:
        free(scratch)
    return status, step, n_rec, max_tau, iref_out
