# The tables' type, shared by every wrapper (tab.h).
cdef extern from "tab.h":
    ctypedef struct Tab:
        const double *v
        long n


cdef inline Tab tab_of(const double[:, ::1] T):
    """The C view of a (rows, n) float64 C-contiguous table array."""
    cdef Tab tab
    tab.v = &T[0, 0]
    tab.n = T.shape[1]
    return tab
