# command.h, feedforward.h and control.h: the controller sample, the commands and the
# feedforward, for the integrators' callers and the tests.
cdef extern from "api_control.h":
    double st_controller_sample(double t, double *x, const double *P, Tab T, double *work) nogil
    double st_controller_update(double r, double *x, const double *P, Tab T, double *work,
                                double i_ff, double w_ff) nogil
    void st_continuous_command(double t, const double *P, Tab T, double *r, double *i_ff, double *w_ff) nogil
    double st_reference(double t, const double *P) nogil
    double st_command(double t, const double *P) nogil
    void st_feedforward(double t, const double *P, Tab T, double *r, double *i_ff, double *w_ff) nogil
    double st_motor_angle(const double *P, Tab T, double p) nogil
    double st_measured_angle(double q, const double *P) nogil
    double st_measured_motor_angle(const double *P, Tab T, double p) nogil
    double st_motion(const double *x, const double *P, double r, double th, double wm, double *dx, long base,
                     int write_state) nogil
    void st_schedule_factors(const double *P, double q, double *g_e, double *g_w) nogil
    void st_table_rates(double t, const double *P, double *r, double *rd, double *rdd) nogil
    void st_move_rates(double t, const double *P, double *r, double *rd, double *rdd) nogil


cdef inline double *_out(double[::1] a):
    """The data of a writable 1-D array (NULL when it is empty: nothing is written there)."""
    return NULL if a.shape[0] == 0 else &a[0]


def controller_sample(double t, double[::1] x, const double[::1] P, const double[:, ::1] T, double[::1] work):
    """Sampled motion controller at time t: returns the held i_ref, updates x[NX_PHYS:] (and
    the speed estimator's states) and work (the controller's next state)."""
    return st_controller_sample(t, &x[0], &P[0], tab_of(T), _out(work))


def controller_update(double r, double[::1] x, const double[::1] P, const double[:, ::1] T, double[::1] work,
                      double i_ff, double w_ff):
    """The controller sample at the reference r with the feedforward current i_ff and speed
    w_ff: returns the held i_ref, updates x[NX_PHYS:] and work."""
    return st_controller_update(r, &x[0], &P[0], tab_of(T), _out(work), i_ff, w_ff)


def continuous_command(double t, const double[::1] P, const double[:, ::1] T):
    """The continuous controller's reference and feedforward at time t: ``(r, i_ff, w_ff)``."""
    cdef double r, i_ff, w_ff
    st_continuous_command(t, &P[0], tab_of(T), &r, &i_ff, &w_ff)
    return r, i_ff, w_ff


def reference(double t, const double[::1] P):
    """The position reference at time t (the command or move, through the command shaper)."""
    return st_reference(t, &P[0])


def command(double t, const double[::1] P):
    """The position command at time t, before the command shaper."""
    return st_command(t, &P[0])


def feedforward(double t, const double[::1] P, const double[:, ::1] T):
    """The reference and the feedforward at a controller sample at time t: ``(r, i_ff, w_ff)``."""
    cdef double r, i_ff, w_ff
    st_feedforward(t, &P[0], tab_of(T), &r, &i_ff, &w_ff)
    return r, i_ff, w_ff


def motor_angle(const double[::1] P, const double[:, ::1] T, double p):
    """Motor angle (rad, 0 at mid-stroke) at motor-side position p."""
    return st_motor_angle(&P[0], tab_of(T), p)


def measured_angle(double q, const double[::1] P):
    """Output encoder: q rounded to the encoder's least significant bit (0 = ideal)."""
    return st_measured_angle(q, &P[0])


def measured_motor_angle(const double[::1] P, const double[:, ::1] T, double p):
    """Motor encoder: the motor angle rounded to the encoder's count (0 = unquantized)."""
    return st_measured_motor_angle(&P[0], tab_of(T), p)


def motion(const double[::1] x, const double[::1] P, double r, double th, double wm, double[::1] dx, long base,
           bint write_state):
    """Motion controller: output i_ref (unclamped); with write_state its next state (sampled)
    or derivative (continuous) into dx[base:base + NC]."""
    return st_motion(&x[0], &P[0], r, th, wm, _out(dx), base, write_state)


def schedule_factors(const double[::1] P, double q):
    """The gain schedule's factors at the measured output position q: ``(g_e, g_w)``."""
    cdef double g_e, g_w
    st_schedule_factors(&P[0], q, &g_e, &g_w)
    return g_e, g_w


def table_rates(double t, const double[::1] P):
    """The sampled command and its first and second time derivatives at time t: ``(r, r', r'')``."""
    cdef double r, rd, rdd
    st_table_rates(t, &P[0], &r, &rd, &rdd)
    return r, rd, rdd


def move_rates(double t, const double[::1] P):
    """The jerk-limited move at time t: ``(r, r', r'')``."""
    cdef double r, rd, rdd
    st_move_rates(t, &P[0], &r, &rd, &rdd)
    return r, rd, rdd
