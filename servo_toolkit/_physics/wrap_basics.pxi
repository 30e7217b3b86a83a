# vmath.h and tables.h, for the tests and the callers that need one value.
cdef extern from "api_basics.h":
    const double st_tanh_one
    const double st_tanh_small
    double st_tanh(double a) nogil
    double st_exp_pos(double y) nogil
    double st_exp_neg(double y) nogil
    void st_hermite(Tab T, long row, const double *P, double q, double *val, double *der) nogil


#: |a| from which tanh(a) rounds to +-1 in double precision (vmath.h's TANH_ONE)
TANH_ONE = st_tanh_one
#: below this |a| tanh is the rational form, above it 1 - 2 / (exp(2 |a|) + 1) (TANH_SMALL)
TANH_SMALL = st_tanh_small


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
