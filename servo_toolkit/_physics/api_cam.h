/* Entry points of cam.h (the cam drive's kernels) for the extension module. */
#ifndef SERVO_API_CAM_H
#define SERVO_API_CAM_H

void st_cam_law(double theta, double a, double *s, double *d1, double *d2);
void st_cam_friction(const double *p, double s, double d1, double sigma, double frictionless, double f0,
                     double *force, double *f);
double st_cam_speed_step(const double *p, double voltage, double w, double load, double inertia, double step);
long st_cam_discrete(const double *p, double voltage, long n, double step, int corrected, double *theta,
                     double *omega);
void st_cam_shaft_acceleration(const double *p, double theta, double w, double torque, double inertia,
                               double velocity_torque, double inv_ws, double *dw, double *m_g);
void st_cam_rhs(const double *p, double voltage, double theta, double w, int double_count, double *dtheta,
                double *dw);

#endif
