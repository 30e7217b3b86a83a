# rhs.h, friction.h and compliance.h: the closed loop's right-hand side and the friction and
# contact laws, for the callers that evaluate them once and for the tests.
cdef extern from "api_rhs.h":
    long st_rhs_nx_phys() nogil
    long st_rhs_naux() nogil
    void st_rhs(double t, double *x, long nx, const double *P, Tab T, double iref_held, double *dx,
                double *aux) nogil
    void st_rhs_phys(double t, double p, double pd, double q, double qd, double cur, double xi, double s,
                     const double *P, Tab T, double iref_held, double *x, double *dx, double *out) nogil
    double st_contact(double tau_c, double tau_d) nogil
    double st_speed_sign(double n, double tw) nogil
    double st_slip_friction(double v, double tc, double ts, double inv_vs, double direction) nogil
    double st_stuck_or_breaking(double applied, double cap) nogil
    double st_gear_at_rest(double torque, double moment, double cap_t, double cap_m, double fwd_loss,
                           double back_loss, double gauge) nogil


def rhs(double t, const double[::1] x, const double[::1] P, const double[:, ::1] T, double iref_held,
        double[::1] dx, double[::1] aux):
    """dx/dt of the closed loop at time t and state x into ``dx`` (x's size); ``aux`` receives
    the current, voltage, current reference and motor torque (``AUX_*``). x is only read."""
    cdef long nx = x.shape[0]
    if nx < st_rhs_nx_phys() or dx.shape[0] < nx or aux.shape[0] < st_rhs_naux():
        raise ValueError(f"rhs: x has {nx} states (at least {st_rhs_nx_phys()}), dx {dx.shape[0]}, "
                         f"aux {aux.shape[0]} (at least {st_rhs_naux()})")
    st_rhs(t, <double *>&x[0], nx, &P[0], tab_of(T), iref_held, &dx[0], &aux[0])


def rhs_phys(double t, double p, double pd, double q, double qd, double cur, double xi, double s,
             const double[::1] P, const double[:, ::1] T, double iref_held, const double[::1] x,
             double[::1] dx):
    """The physical states' derivatives at the scalars (p, p', q, q', i, xi, s):
    ``(p', pd', q', qd', i', xi', i, v, i_ref, tau_m)``. The continuous motion controller and
    the full chain's intermediate nodes read their states in ``x`` (only read) and write their
    derivatives into ``dx`` (x's size)."""
    cdef double out[10]
    if x.shape[0] < st_rhs_nx_phys() or dx.shape[0] < x.shape[0]:
        raise ValueError(f"rhs_phys: x has {x.shape[0]} entries (at least {st_rhs_nx_phys()}), dx {dx.shape[0]}")
    st_rhs_phys(t, p, pd, q, qd, cur, xi, s, &P[0], tab_of(T), iref_held, <double *>&x[0], &dx[0], out)
    return (out[0], out[1], out[2], out[3], out[4], out[5], out[6], out[7], out[8], out[9])


def contact(double tau_c, double tau_d):
    """The elasto-backlash contact moment from its spring part ``tau_c`` and damper part ``tau_d``."""
    return st_contact(tau_c, tau_d)


def speed_sign(double n, double tw):
    """The output speed's smooth sign tanh(|N| p' / w_s) from the motor speed's
    ``tw`` = tanh(N p' / w_s), for a ratio ``n`` of either sign."""
    return st_speed_sign(n, tw)


def slip_friction(double v, double tc, double ts, double inv_vs, double direction):
    """The Stribeck sliding friction at speed v (signed with ``direction`` when it is not 0)."""
    return st_slip_friction(v, tc, ts, inv_vs, direction)


def stuck_or_breaking(double applied, double cap):
    """The net moment on a node at rest: 0 within the breakaway level ``cap``, else beyond it."""
    return st_stuck_or_breaking(applied, cap)


def gear_at_rest(double torque, double moment, double cap_t, double cap_m, double fwd_loss, double back_loss,
                 double gauge):
    """The net moment (or, ``gauge`` 1 or 2, the breakaway gauge) on a node at rest behind a lossy gear."""
    return st_gear_at_rest(torque, moment, cap_t, cap_m, fwd_loss, back_loss, gauge)
