/* Scalar kernels of the cam drive, for the time-stepping loops (the Python face, with the
   packer of p: servo_toolkit.components.cam.kernels).

   They evaluate exactly the physics of servo_toolkit.components.cam.drive (the tests check
   the kernels against the vectorized component law and CamDrive.follower_force).
   p is the flat parameter array built by kernels.pack (Python):

       [A, m, mu, G_x, G_y, |G_z|, r0, stroke, J_m, M_f, R, c_m, c_e, clearance]

   Each kernel performs the component law's operations in the same order. */
#ifndef SERVO_CAM_H
#define SERVO_CAM_H

#include "common.h"

/* pi (M_PI is not C99) */
#define CAM_PI 3.14159265358979323846

/* Python's float modulo: the result takes the divisor's sign */
static inline double cam_pymod(double a, double b)
{
    double r = fmod(a, b);
    if (r != 0.0) {
        if ((b < 0.0) != (r < 0.0))
            r += b;
    } else {
        r = copysign(0.0, b);
    }
    return r;
}

/* Modified constant velocity law: s, ds/dtheta, d2s/dtheta2. */
static inline void law(double theta, double a, double *s, double *d1, double *d2)
{
    const double q = CAM_PI / 4;
    double th = cam_pymod(theta, 2 * CAM_PI);
    double s4 = sin(4 * th), c4 = cos(4 * th);
    double tr = th - s4 / 4;
    if (th < q) {
        *s = a * tr; *d1 = a * (1 - c4); *d2 = 4 * a * s4;
    } else if (th < 3 * q) {
        *s = 2 * a * th - CAM_PI * a / 4; *d1 = 2 * a; *d2 = 0.0;
    } else if (th < 4 * q) {
        *s = CAM_PI * a / 2 + a * tr; *d1 = a * (1 - c4); *d2 = 4 * a * s4;
    } else if (th < 5 * q) {
        *s = 2.5 * CAM_PI * a - a * tr; *d1 = -a * (1 - c4); *d2 = -4 * a * s4;
    } else if (th < 7 * q) {
        *s = 3.75 * CAM_PI * a - 2 * a * th; *d1 = -2 * a; *d2 = 0.0;
    } else {
        *s = 2 * CAM_PI * a - a * tr; *d1 = -a * (1 - c4); *d2 = -4 * a * s4;
    }
}

/* Fixed point of the guide friction for a frictionless cam force; returns (P, f). */
static inline void friction(const double *p, double s, double d1, double sigma, double frictionless,
                            double f0, double *force_out, double *f_out)
{
    double f = f0;
    for (int it = 0; it < 60; it++) {
        double force = frictionless + sigma * f;
        double rho = force >= 0 ? p[6] + s : p[6] + p[7] - s;
        double side = fabs(force) * d1 / rho + p[4];
        double nw = p[2] * (fabs(side) + p[5]);
        if (fabs(nw - f) <= 1e-14 * (1.0 + nw)) {
            f = nw;
            break;
        }
        f = nw;
    }
    *force_out = frictionless + sigma * f;
    *f_out = f;
}

static inline double cam_sign(double x)
{
    return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0);
}

/* One RK4 step of eq 12 for w with the load torque M and inertia J frozen (step 2 of
   the seed's scheme). */
static inline double speed_step(const double *p, double voltage, double w, double load, double inertia,
                                double step)
{
    double r = p[10], cm = p[11], ce = p[12];
    double k1 = (cm * voltage - r * load - ce * cm * w) / (r * inertia);
    double k2 = (cm * voltage - r * load - ce * cm * (w + 0.5 * step * k1)) / (r * inertia);
    double k3 = (cm * voltage - r * load - ce * cm * (w + 0.5 * step * k2)) / (r * inertia);
    double k4 = (cm * voltage - r * load - ce * cm * (w + step * k3)) / (r * inertia);
    return w + step * (k1 + 2 * k2 + 2 * k3 + k4) / 6;
}

/* Seed 002 section 3; `corrected` drops the inertia that eq 4 already holds.

   Fills theta, omega (n + 1 samples, zeroed first) and returns a status: 0 ok, 1 non-finite,
   2 reversed. */
static inline long discrete(const double *p, double voltage, long n, double step, int corrected,
                            double *theta, double *omega)
{
    double a_ = p[0], m = p[1], jm = p[8], mf = p[9], c = p[13];
    for (long k = 0; k <= n; k++) {
        theta[k] = 0.0;
        omega[k] = 0.0;
    }
    double s_in = 0.0, s_out = 0.0, v = 0.0;
    double load = mf, inertia = jm;
    for (long k = 0; k < n; k++) {
        double w = omega[k];
        double wn = speed_step(p, voltage, w, load, inertia, step);
        if (!isfinite(wn))
            return 1;
        if (wn < 0)
            return 2;
        omega[k + 1] = wn;
        theta[k + 1] = theta[k] + wn * step;
        double s_new_in, d1, d2;
        law(theta[k + 1], a_, &s_new_in, &d1, &d2);
        double s_new = s_new_in;
        if (c > 0) { /* eqs 6-8 */
            if (s_new_in > s_in && s_new_in > s_out + c)
                s_new = s_new_in - c;
            else if (s_new_in < s_in && s_new_in < s_out - c)
                s_new = s_new_in + c;
            else
                s_new = s_out;
        }
        double vn = (s_new - s_out) / step;
        double an = (vn - v) / step;
        s_in = s_new_in;
        s_out = s_new;
        v = vn;
        double acc = an;
        if (corrected) /* keep only m s' s'' w^2 of m a: eq 4's J carries m s'^2 w' */
            acc = an - d1 * (wn - w) / step;
        double force, f;
        friction(p, s_new_in, d1, cam_sign(vn), m * acc - p[3], 0.0, &force, &f);
        load = mf + force * d1;
        double ratio = wn > 0 ? vn / wn : d1;
        inertia = jm + m * ratio * ratio;
    }
    return 0;
}

/* Cam-shaft acceleration with the follower's weight and guide friction (eqs 1, 3).

   Solves J w' + velocity_torque = torque - M_g with the follower load beyond its inertia,
   M_g = (sigma f - G_x) ds/dtheta, where the guide friction f (eq 1, via friction) depends
   on the cam force m a - G_x + sigma f and so on w' through a = s'' w^2 + s' w'; the fixed
   point is iterated to round-off.

   p: pack array (motor entries unused); theta, w: cam angle (rad) and speed (rad/s);
   torque: every other torque on the cam shaft, reflected to it (N*m): motor torque after its
   own friction, the scene's load moments; inertia, velocity_torque: J(theta) with the
   follower's m s'^2 (kg*m^2) and the velocity term J'(theta) w^2 / 2 (N*m), as the caller's
   model has them; inv_ws: 1 / smoothing speed (s/rad) of the friction's direction,
   tanh(w / w_s); 0 for the hard sign.
   Out: dw = w' (rad/s^2) and m_g = M_g (N*m).

   The direction's tanh is the C library's, as in the component law (not the right-hand side's
   vtanh). */
static inline void shaft_acceleration(const double *p, double theta, double w, double torque, double inertia,
                                      double velocity_torque, double inv_ws, double *dw, double *m_g)
{
    double s, d1, d2;
    law(theta, p[0], &s, &d1, &d2);
    double m = p[1];
    double sigma;
    if (inv_ws > 0.0)
        sigma = cam_sign(d1) * tanh(w * inv_ws);
    else
        sigma = cam_sign(d1 * w);
    double f = 0.0;
    double acc_dw = 0.0;
    for (int it = 0; it < 60; it++) {
        acc_dw = (torque - velocity_torque - d1 * (sigma * f - p[3])) / inertia;
        double acc = d2 * w * w + d1 * acc_dw;
        double force, nw;
        friction(p, s, d1, sigma, m * acc - p[3], f, &force, &nw);
        if (fabs(nw - f) <= 1e-14 * (1.0 + nw)) {
            f = nw;
            break;
        }
        f = nw;
    }
    *dw = (torque - velocity_torque - d1 * (sigma * f - p[3])) / inertia;
    *m_g = d1 * (sigma * f - p[3]);
}

/* d(theta)/dt, dw/dt of J w' + J' w^2 / 2 = c_m i - M (double_count: the seed's continuous
   limit, with the follower inertia in both J and m a). */
static inline void cam_rhs(const double *p, double voltage, double theta, double w, int double_count,
                           double *dtheta, double *dw)
{
    double m = p[1], jm = p[8], mf = p[9], r = p[10], cm = p[11], ce = p[12];
    double s, d1, d2;
    law(theta, p[0], &s, &d1, &d2);
    double torque = cm * (voltage - ce * w) / r - mf;
    double j = jm + m * d1 * d1 * (double_count ? 2.0 : 1.0);
    double m_g;
    shaft_acceleration(p, theta, w, torque, j, m * d1 * d2 * w * w, 0.0, dw, &m_g);
    *dtheta = w;
}

#endif
