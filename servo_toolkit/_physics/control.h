/* The controller sample update and the motion controller (the right-hand side is rhs.h; both
   exported to Python by servo_toolkit.sim.kernel). Layout of x and P in
   servo_toolkit/sim/layout.py.

   The motion controller is a discrete (sampled) or continuous state-space system
   (A, B, C, D at P[OFF_A..OFF_D], NC states in x[NX_PHYS:]) whose inputs are the reference
   theta_ref, the measured output angle theta (quantized by the output encoder) and the motor
   speed omega_m (true, or estimated from the quantized motor encoder); its output is the
   current reference i_ref, clamped at the current limit. The sampled controller's update is
   controller_sample (once per sample, never per integration stage); the continuous one's
   derivative is motion with write_state, inside the right-hand side, whose reference and
   feedforward are continuous_command. */
#ifndef SERVO_CONTROL_H
#define SERVO_CONTROL_H

#include "common.h"
#include "tables.h"
#include "command.h"
#include "feedforward.h"

/* Clamp v to [-lim, lim]. */
static inline double clip(double v, double lim)
{
    if (v > lim)
        return lim;
    if (v < -lim)
        return -lim;
    return v;
}

/* Motion controller: output i_ref (unclamped); with write_state, the state update (sampled) or
   derivative (continuous) into dx[base:base + NC]. */
static inline double motion(const double *x, const double *P, double r, double th, double wm, double *dx, long base,
                            int write_state)
{
    long nc = IX(P[NC]);
    long oa = IX(P[OFF_A]), ob = IX(P[OFF_B]), oc = IX(P[OFF_C]), od = IX(P[OFF_D]);
    double y = P[od] * r + P[od + 1] * th + P[od + 2] * wm;
    for (long j = 0; j < nc; j++)
        y += P[oc + j] * x[NX_PHYS + j];
    if (write_state) {
        for (long j = 0; j < nc; j++) {
            double acc = P[ob + 3 * j] * r + P[ob + 3 * j + 1] * th + P[ob + 3 * j + 2] * wm;
            for (long k = 0; k < nc; k++)
                acc += P[oa + j * nc + k] * x[NX_PHYS + k];
            dx[base + j] = acc;
        }
    }
    return y;
}

/* Output encoder: q rounded to the encoder's least significant bit (0 = ideal). */
static inline double measured_angle(double q, const double *P)
{
    double lsb = P[LSB];
    if (lsb > 0.0)
        return lsb * floor(q / lsb + 0.5);
    return q;
}

/* Motor angle (rad, 0 at mid-stroke) at motor-side position p; periodic tables add one table
   period's motor travel per wrap. */
static inline double motor_angle(const double *P, Tab T, double p)
{
    double val, der;
    hermite(T, T_M, P, p, &val, &der);
    if (P[PERIODIC] > 0.0) {
        double last = P[TAB_N] - 1.0;
        double wraps = floor((p - P[TAB_LO]) * P[INV_H] / last);
        val += wraps * (TAB(T, T_M, (long)last) - TAB(T, T_M, 0));
    }
    return val;
}

/* Motor encoder: the motor angle rounded to the encoder's count (0 = unquantized). */
static inline double measured_motor_angle(const double *P, Tab T, double p)
{
    double th = motor_angle(P, T, p);
    double lsb = P[LSB_M];
    if (lsb > 0.0)
        return lsb * floor(th / lsb + 0.5);
    return th;
}

/* Motor speed for the speed loop: the true speed ("ideal"), or an estimate from the motor
   encoder updated once per sample (its states follow the controller's in x, which are
   updated).

   "difference": (z_k - z_{k-1}) / Ts. "kalman": constant-gain filter, predict x <- F x,
   update x <- x + K (z - x[0]) (the measurement is the angle, H = [1, 0, 0]). */
static inline double speed_estimate(double *x, const double *P, Tab T, double wm_true)
{
    long est = IX(P[EST]);
    if (est == 0)
        return wm_true;
    double z = measured_motor_angle(P, T, x[0]);
    long e = IX(P[OFF_E]);
    if (est == EST_DIFFERENCE) {
        double wm = (z - x[e]) * P[INV_TS];
        x[e] = z;
        x[e + 1] = wm;
        return wm;
    }
    long o = IX(P[OFF_KF]);
    double a0 = x[e], a1 = x[e + 1], a2 = x[e + 2];
    double p0 = P[o] * a0 + P[o + 1] * a1 + P[o + 2] * a2;
    double p1 = P[o + 3] * a0 + P[o + 4] * a1 + P[o + 5] * a2;
    double p2 = P[o + 6] * a0 + P[o + 7] * a1 + P[o + 8] * a2;
    double inn = z - p0;
    x[e] = p0 + P[o + 9] * inn;
    x[e + 1] = p1 + P[o + 10] * inn;
    x[e + 2] = p2 + P[o + 11] * inn;
    return x[e + 1];
}

/* The motion controller's measurements at the state x: the output angle as the output encoder
   reads it (*th) and the motor speed, true or estimated (*wm; speed_estimate, whose states in x
   are updated). */
static inline void controller_inputs(double *x, const double *P, Tab T, double *th, double *wm)
{
    double n, dn;
    hermite(T, T_N, P, x[0], &n, &dn);
    *wm = speed_estimate(x, P, T, n * x[1]);
    *th = measured_angle(x[2], P);
}

/* The sample of controller_sample at a given reference r: returns the held i_ref (the motion
   controller's output plus the feedforward current i_ff, clamped at the current limit),
   updates x[NX_PHYS:] (work: NC doubles of scratch). The speed loop sees the measured motor
   speed less the feedforward's speed reference w_ff (0 without one). A gain schedule (SCHED)
   scales the controller's position-error inputs and its speed input by its factors at the
   measured output angle (schedule_factors). With back-calculation gains (AW: every sampled
   controller with an integrator) a clamped sample moves the controller's integrator by the
   clamp's excess (its next output starts at the limit: the integral does not wind up while
   the current is limited, whether the feedback or a feedforward's share holds the limit).

   The output angle is quantized by the output encoder; the motor speed is the true omega_m or,
   per the model's speed estimator, an estimate from the (quantized) motor encoder
   (controller_inputs). */
static inline double controller_update(double r, double *x, const double *P, Tab T, double *work, double i_ff,
                                       double w_ff)
{
    long nc = IX(P[NC]);
    double th, wm, ge, gw;
    controller_inputs(x, P, T, &th, &wm);
    schedule_factors(P, th, &ge, &gw);
    double y = motion(x, P, ge * r, ge * th, gw * (wm - w_ff), work, 0, 1) + i_ff;
    long o = IX(P[AW]);
    if (o > 0 && fabs(y) > P[ILIM]) {
        /* back-calculation at the clamp: the controller's integrator takes the excess, so it
           does not wind up while the current is limited */
        double excess = clip(y, P[ILIM]) - y;
        for (long j = 0; j < nc; j++)
            work[j] += P[o + j] * excess;
    }
    for (long j = 0; j < nc; j++)
        x[NX_PHYS + j] = work[j];
    return clip(y, P[ILIM]);
}

/* Sampled motion controller at time t: returns the held i_ref, updates x[NX_PHYS:]
   (controller_update at the reference r(t), plus the feedforward current along r(t), r'(t),
   r''(t) when FF_ON: once per sample, never per integration stage). */
static inline double controller_sample(double t, double *x, const double *P, Tab T, double *work)
{
    if (P[FF_ON] > 0.0) {
        double r, i_ff, w_ff;
        feedforward(t, P, T, &r, &i_ff, &w_ff);
        return controller_update(r, x, P, T, work, i_ff, w_ff);
    }
    return controller_update(reference(t, P), x, P, T, work, 0.0, 0.0);
}

/* The continuous controller's reference and feedforward at time t, (*r, *i_ff, *w_ff)
   (feedforward when FF_ON, else (r(t), 0, 0)). */
static inline void continuous_command(double t, const double *P, Tab T, double *r, double *i_ff, double *w_ff)
{
    if (P[FF_ON] > 0.0) {
        feedforward(t, P, T, r, i_ff, w_ff);
        return;
    }
    *r = reference(t, P);
    *i_ff = 0.0;
    *w_ff = 0.0;
}

#endif
