# cam.h: the cam drive's kernels (servo_toolkit.components.cam.kernels imports them under
# their short names).
import numpy as np

cdef extern from "api_cam.h":
    void st_cam_law(double theta, double a, double *s, double *d1, double *d2) nogil
    void st_cam_friction(const double *p, double s, double d1, double sigma, double frictionless, double f0,
                         double *force, double *f) nogil
    double st_cam_speed_step(const double *p, double voltage, double w, double load, double inertia,
                             double step) nogil
    long st_cam_discrete(const double *p, double voltage, long n, double step, int corrected, double *theta,
                         double *omega) nogil
    void st_cam_shaft_acceleration(const double *p, double theta, double w, double torque, double inertia,
                                   double velocity_torque, double inv_ws, double *dw, double *m_g) nogil
    void st_cam_rhs(const double *p, double voltage, double theta, double w, int double_count,
                    double *dtheta, double *dw) nogil


def cam_law(double theta, double a):
    """Modified constant velocity law: ``(s, ds/dtheta, d2s/dtheta2)``."""
    cdef double s, d1, d2
    st_cam_law(theta, a, &s, &d1, &d2)
    return s, d1, d2


def cam_friction(const double[::1] p, double s, double d1, double sigma, double frictionless, double f0):
    """Fixed point of the guide friction for a frictionless cam force: ``(P, f)``."""
    cdef double force, f
    st_cam_friction(&p[0], s, d1, sigma, frictionless, f0, &force, &f)
    return force, f


def cam_speed_step(const double[::1] p, double voltage, double w, double load, double inertia, double step):
    """One RK4 step of eq 12 for w with the load torque and inertia frozen."""
    return st_cam_speed_step(&p[0], voltage, w, load, inertia, step)


def cam_discrete(const double[::1] p, double voltage, long n, double step, bint corrected):
    """The seed's discrete scheme: ``(theta, omega, status)`` (n + 1 samples; status 0 ok,
    1 non-finite, 2 reversed)."""
    if n < 0:
        raise ValueError("cam_discrete: n must be >= 0")
    theta = np.zeros(n + 1)
    omega = np.zeros(n + 1)
    cdef double[::1] th = theta
    cdef double[::1] om = omega
    cdef long status
    with nogil:
        status = st_cam_discrete(&p[0], voltage, n, step, corrected, &th[0], &om[0])
    return theta, omega, status


def cam_shaft_acceleration(const double[::1] p, double theta, double w, double torque, double inertia,
                           double velocity_torque, double inv_ws):
    """Cam-shaft acceleration with the follower's weight and guide friction: ``(dw, m_g)``."""
    cdef double dw, m_g
    st_cam_shaft_acceleration(&p[0], theta, w, torque, inertia, velocity_torque, inv_ws, &dw, &m_g)
    return dw, m_g


def cam_rhs(const double[::1] p, double voltage, double theta, double w, bint double_count):
    """``(d theta/dt, dw/dt)`` of the cam drive at constant voltage."""
    cdef double dtheta, dw
    st_cam_rhs(&p[0], voltage, theta, w, double_count, &dtheta, &dw)
    return dtheta, dw
