/* Commands and gain schedule inside the kernels: the position reference r(t) and its command
   (sine, step, ramp, table), the jerk-limited move, the command shaper's impulses and the gain
   schedule along the stroke (slots in servo_toolkit/sim/layout.py; the host side in
   servo_toolkit.loop.profile, servo_toolkit.loop.shaper and servo_toolkit.loop.schedule;
   reference, command and schedule_factors exported by servo_toolkit.sim.kernel, table_rates
   and move_rates by servo_toolkit._physics._kernels).

   The sampled command is the cubic Hermite interpolant of a table of samples stored in P after
   the header, with its exact first and second time derivatives (slots REF_TAB_*; packed by
   servo_toolkit.sim.reference_table). On segment k (between samples k and k + 1, local
   coordinate u in [0, 1], spacing h):

       r(u)  = h00 y_k + h h10 m_k + h01 y_k+1 + h h11 m_k+1
       r'    = (6u^2 - 6u)(y_k - y_k+1) / h + (3u^2 - 4u + 1) m_k + (3u^2 - 2u) m_k+1
       r''   = ((12u - 6)(y_k - y_k+1) / h + (6u - 4) m_k + (6u - 2) m_k+1) / h

   With the slopes of a cubic spline through the samples (what the packer stores) r is that
   spline: twice continuously differentiable. Outside a non-periodic table the end values are
   held (r' = r'' = 0); a periodic table wraps. */
#ifndef SERVO_COMMAND_H
#define SERVO_COMMAND_H

#include "common.h"

/* math.pi */
#define ST_PI 3.141592653589793

/* The sampled command and its first and second time derivatives at time t, (*r, *rd, *rdd):
   REF_OFF plus the table's interpolant. */
static inline void table_rates(double t, const double *P, double *r, double *rd, double *rdd)
{
    long o = IX(P[REF_TAB_OFF]);
    long n = IX(P[REF_TAB_N]);
    double inv = P[REF_TAB_INV_DT];
    double last = n - 1.0;
    double s = (t - P[REF_TAB_T0]) * inv;
    double moving = 1.0;
    if (P[REF_TAB_WRAP] > 0.0) {
        s = s - last * floor(s / last);
    } else if (s <= 0.0) {
        s = 0.0;
        moving = 0.0;
    } else if (s >= last) {
        s = last;
        moving = 0.0;
    }
    long k = (long)s;
    if (k > n - 2)
        k = n - 2;
    double u = s - (double)k;
    double dy = P[o + k] - P[o + k + 1];
    double m0 = P[o + n + k];
    double m1 = P[o + n + k + 1];
    double h = 1.0 / inv;
    double u2 = u * u;
    double val = P[o + k] + u2 * (2.0 * u - 3.0) * dy + h * ((u2 * u - 2.0 * u2 + u) * m0 + (u2 * u - u2) * m1);
    double der = (6.0 * u2 - 6.0 * u) * dy * inv + (3.0 * u2 - 4.0 * u + 1.0) * m0 + (3.0 * u2 - 2.0 * u) * m1;
    double acc = ((12.0 * u - 6.0) * dy * inv + (6.0 * u - 4.0) * m0 + (6.0 * u - 2.0) * m1) * inv;
    *r = P[REF_OFF] + val;
    *rd = moving * der;
    *rdd = moving * acc;
}

/* The jerk-limited move (REF_MOVE) at time t: (*r, *rd, *rdd).

   Seven segments from REF_T0: jerk +j for the jerk time Tj, constant acceleration for Ta,
   jerk -j for Tj, constant speed for Tv, then the acceleration's mirror image
   (r(T - s) = D - r(s), r' even and r'' odd about the middle of the move); the start value
   REF_OFF before it, the end value after it. The block at P[REF_F] holds
   [signed jerk, Tj, Ta, Tv] (servo_toolkit.loop.profile.MoveProfile). */
static inline void move_rates(double t, const double *P, double *r, double *rd, double *rdd)
{
    long o = IX(P[REF_F]);
    double j = P[o], tj = P[o + 1], ta = P[o + 2], tv = P[o + 3];
    double t3 = 2.0 * tj + ta; /* end of the acceleration */
    double a = j * tj;         /* peak acceleration */
    double vp = a * (tj + ta); /* cruise speed */
    double p3 = 0.5 * vp * t3; /* distance of the acceleration */
    double u = dmin(dmax(t - P[REF_T0], 0.0), 2.0 * t3 + tv);
    int back = u > t3 + tv;
    double p, v, acc;
    if (back)
        u = 2.0 * t3 + tv - u;
    if (u <= tj) {
        p = j * u * u * u / 6.0;
        v = 0.5 * j * u * u;
        acc = j * u;
    } else if (u <= tj + ta) {
        double w = u - tj;
        p = j * tj * tj * tj / 6.0 + 0.5 * j * tj * tj * w + 0.5 * a * w * w;
        v = 0.5 * j * tj * tj + a * w;
        acc = a;
    } else if (u <= t3) {
        double w = t3 - u;
        p = p3 - vp * w + j * w * w * w / 6.0;
        v = vp - 0.5 * j * w * w;
        acc = j * w;
    } else {
        p = p3 + vp * (u - t3);
        v = vp;
        acc = 0.0;
    }
    if (back) {
        p = 2.0 * p3 + vp * tv - p;
        acc = -acc;
    }
    *r = P[REF_OFF] + p;
    *rd = v;
    *rdd = acc;
}

/* The command shaper's impulse count: 3 with a shaper (SHAPE_A0 > 0; a ZV's third amplitude
   is 0), else 1 (the command itself). */
static inline long impulses(const double *P)
{
    return P[SHAPE_A0] > 0.0 ? 3 : 1;
}

/* Amplitude *amp and delay *delay (s) of impulse i of the command shaper; (1, 0) without one. */
static inline void impulse(const double *P, long i, double *amp, double *delay)
{
    if (P[SHAPE_A0] <= 0.0) {
        *amp = 1.0;
        *delay = 0.0;
        return;
    }
    *amp = P[SHAPE_A0 + i];
    *delay = i == 0 ? 0.0 : P[SHAPE_T1 + i - 1];
}

/* The gain schedule's factors at the measured output position q: (*g_e, *g_w), the factor on
   the position-error inputs (theta_ref, theta) and on the speed input (omega_m) of the motion
   controller; (1, 1) without a schedule. Linear between the schedule's points, its end values
   held beyond them (the table a drive interpolates). */
static inline void schedule_factors(const double *P, double q, double *g_e, double *g_w)
{
    long o = IX(P[SCHED]);
    if (o == 0) {
        *g_e = 1.0;
        *g_w = 1.0;
        return;
    }
    long n = IX(P[o]);
    double s = (q - P[o + 1]) * P[o + 2];
    long k;
    double f;
    if (s <= 0.0) {
        k = 0;
        f = 0.0;
    } else if (s >= n - 1.0) {
        k = n - 2;
        f = 1.0;
    } else {
        k = (long)s;
        f = s - (double)k;
    }
    long e = o + 3 + k;
    long w = e + n;
    *g_e = P[e] + f * (P[e + 1] - P[e]);
    *g_w = P[w] + f * (P[w + 1] - P[w]);
}

/* The position command at time t, before the command shaper (the move, move_rates, is a
   closed-loop command: reference). */
static inline double command(double t, const double *P)
{
    long kind = IX(P[REF_KIND]);
    if (kind == REF_SINE)
        return P[REF_OFF] + P[REF_A] * sin(2.0 * ST_PI * P[REF_F] * (t - P[REF_T0]));
    if (kind == REF_STEP)
        return P[REF_OFF] + (t >= P[REF_T0] ? P[REF_A] : 0.0);
    if (kind == REF_RAMP)
        return P[REF_OFF] + P[REF_A] * dmax(t - P[REF_T0], 0.0);
    if (kind == REF_TABLE) {
        double r, rd, rdd;
        table_rates(t, P, &r, &rd, &rdd);
        return r;
    }
    return P[REF_OFF];
}

/* The position reference at time t: the command (command, or the jerk-limited move of
   REF_MOVE), through the command shaper when one is set (SHAPE_A0 > 0): sum_i A_i r(t - t_i)
   over its impulses (servo_toolkit.loop.shaper). */
static inline double reference(double t, const double *P)
{
    int move = IX(P[REF_KIND]) == REF_MOVE;
    double r = 0.0;
    long count = impulses(P);
    for (long i = 0; i < count; i++) {
        double a, d;
        impulse(P, i, &a, &d);
        if (move) {
            double m, md, mdd;
            move_rates(t - d, P, &m, &md, &mdd);
            r += a * m;
        } else {
            r += a * command(t - d, P);
        }
    }
    return r;
}

#endif
