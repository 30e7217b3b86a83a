# vmath.h and tables.h, for the tests and the callers that need one value.
cdef extern from "api_basics.h":
    double st_tanh(double a) nogil
    double st_exp_pos(double y) nogil
    double st_exp_neg(double y) nogil
    void st_hermite(Tab T, long row, const double *P, double q, double *val, double *der) nogil


def tanh(double a):
    """tanh(a) as the right-hand side computes it (within 1 ulp of the C library's)."""
    return st_tanh(a)


def exp_pos(double y):
    """exp(y) for 0 <= y <= 44 as the right-hand side computes it."""
    return st_exp_pos(y)


def exp_neg(double y):
    """exp(-y) for 0 <= y <= 44 as the right-hand side computes it."""
    return st_exp_neg(y)


def hermite(const double[:, ::1] T, long row, const double[::1] P, double q):
    """Table ``row`` at q: ``(value, derivative)`` (cubic Hermite; ends held, periodic wraps)."""
    cdef double val, der
    st_hermite(tab_of(T), row, &P[0], q, &val, &der)
    return val, der
