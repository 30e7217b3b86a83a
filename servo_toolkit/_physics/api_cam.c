/* Exported cam.h functions (see api_cam.h). */
#include "api_cam.h"
#include "cam.h"

void st_cam_law(double theta, double a, double *s, double *d1, double *d2) { law(theta, a, s, d1, d2); }

void st_cam_friction(const double *p, double s, double d1, double sigma, double frictionless, double f0,
                     double *force, double *f)
{
    friction(p, s, d1, sigma, frictionless, f0, force, f);
}

double st_cam_speed_step(const double *p, double voltage, double w, double load, double inertia, double step)
{
    return speed_step(p, voltage, w, load, inertia, step);
}

long st_cam_discrete(const double *p, double voltage, long n, double step, int corrected, double *theta,
                     double *omega)
{
    return discrete(p, voltage, n, step, corrected, theta, omega);
}

void st_cam_shaft_acceleration(const double *p, double theta, double w, double torque, double inertia,
                               double velocity_torque, double inv_ws, double *dw, double *m_g)
{
    shaft_acceleration(p, theta, w, torque, inertia, velocity_torque, inv_ws, dw, m_g);
}

void st_cam_rhs(const double *p, double voltage, double theta, double w, int double_count, double *dtheta,
                double *dw)
{
    cam_rhs(p, voltage, theta, w, double_count, dtheta, dw);
}
