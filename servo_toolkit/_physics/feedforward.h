/* The feedforward current inside the kernels: the reference's analytic derivatives and the
   rigid chain's inverse dynamics along the commanded trajectory
   (servo_toolkit.loop.controller.Feedforward; slots in servo_toolkit/sim/layout.py; exported as
   servo_toolkit.sim.kernel.feedforward). */
#ifndef SERVO_FEEDFORWARD_H
#define SERVO_FEEDFORWARD_H

#include "common.h"
#include "vmath.h"
#include "tables.h"
/* the loss blend and the inertia beyond the motor side */
#include "compliance.h"
#include "command.h"

/* The command and its analytic first and second time derivatives at time t, (*r, *rd, *rdd):
   a sine's, a move's, a ramp's rate (0 before it starts), a sampled command's interpolant
   (table_rates), 0 for a hold and a step (the step's impulses are not fed forward). */
static inline void command_rates(double t, const double *P, double *r, double *rd, double *rdd)
{
    long kind = IX(P[REF_KIND]);
    if (kind == REF_MOVE) {
        move_rates(t, P, r, rd, rdd);
        return;
    }
    if (kind == REF_SINE) {
        double w = 2.0 * ST_PI * P[REF_F];
        double s = sin(w * (t - P[REF_T0]));
        double c = cos(w * (t - P[REF_T0]));
        *r = P[REF_OFF] + P[REF_A] * s;
        *rd = P[REF_A] * w * c;
        *rdd = -P[REF_A] * w * w * s;
        return;
    }
    if (kind == REF_STEP) {
        *r = P[REF_OFF] + (t >= P[REF_T0] ? P[REF_A] : 0.0);
        *rd = 0.0;
        *rdd = 0.0;
        return;
    }
    if (kind == REF_RAMP) {
        if (t > P[REF_T0]) {
            *r = P[REF_OFF] + P[REF_A] * (t - P[REF_T0]);
            *rd = P[REF_A];
            *rdd = 0.0;
            return;
        }
        *r = P[REF_OFF];
        *rd = 0.0;
        *rdd = 0.0;
        return;
    }
    if (kind == REF_TABLE) {
        table_rates(t, P, r, rd, rdd);
        return;
    }
    *r = P[REF_OFF];
    *rd = 0.0;
    *rdd = 0.0;
}

/* The reference and its analytic first and second time derivatives at time t, (*r, *rd, *rdd):
   the command's (command_rates), through the command shaper when one is set (the same impulses
   shape r, r' and r''). */
static inline void reference_rates(double t, const double *P, double *r, double *rd, double *rdd)
{
    double sr = 0.0, srd = 0.0, srdd = 0.0;
    long count = impulses(P);
    for (long i = 0; i < count; i++) {
        double a, d, ri, rdi, rddi;
        impulse(P, i, &a, &d);
        command_rates(t - d, P, &ri, &rdi, &rddi);
        sr += a * ri;
        srd += a * rdi;
        srdd += a * rddi;
    }
    *r = sr;
    *rd = srd;
    *rdd = srdd;
}

/* The feedforward current (A) along the commanded trajectory r, r', r''
   (servo_toolkit.loop.controller.Feedforward): the velocity and acceleration gains' terms plus,
   with FF_MODEL, the rigid chain's inverse dynamics at r from the model's tables (J, J', N, N';
   the inertia offset by FF_DJ, the load the feedforward assumes less the model's), its loss by
   the direction of the power flow (lossy's coefficient, solved for the motor torque), the load's
   hinge moment and damping and the motor's viscous and smoothed Coulomb friction. */
static inline double feedforward_current(double r, double rd, double rdd, const double *P, Tab T)
{
    double i = P[FF_KV] * rd + P[FF_KA] * rdd;
    if (P[FF_MODEL] > 0.0) {
        long kc;
        double tc, j, dj, n, dn, jb, djb;
        cell(P, r, &kc, &tc);
        double hc = P[TAB_H];
        double ih = P[INV_H];
        interp(T, T_J, kc, tc, hc, ih, &j, &dj);
        interp(T, T_N, kc, tc, hc, ih, &n, &dn);
        inertia_beyond_motor(P, T, kc, tc, hc, ih, &jb, &djb); /* the whole chain's J(r), J'(r) */
        j = (j + jb + P[FF_DJ]) * P[FF_JSCALE];
        dj = (dj + djb) * P[FF_JSCALE];
        double m_load = -P[HINGE_M] - P[HINGE_K] * r - P[HINGE_D] * rd;
        double tq = j * rdd + 0.5 * dj * rd * rd - m_load;
        if (P[ETA_MEAN] > 0.0) {
            double jw = P[JW] * n * n * P[FF_JSCALE];
            double tw = jw * rdd + P[JW] * P[FF_JSCALE] * n * dn * rd * rd;
            double tt = tq - tw;
            double sg = vtanh(tt * P[INV_TAU_S]) * vtanh(fabs(n) * rd * P[WS]);
            double c = blend(P, sg);
            tq = tw + tt / (1.0 - c);
        }
        double wm = n * rd;
        i += (tq / n + P[BM] * wm + P[TC] * vtanh(wm * P[WS])) / P[KT];
    }
    return i;
}

/* The reference and the feedforward at a controller sample at time t: (*r, *i_ff, *w_ff).

   r = r(t) is the feedback's reference; w_ff the motor speed along the commanded trajectory,
   N(r) r'(t), which the speed loop takes as its reference (subtracted from the measured motor
   speed; 0 unless FF_SPEED); i_ff the feedforward current (feedforward_current) along the
   trajectory at t + FF_LEAD (half a sample: the middle of the interval over which the
   zero-order hold applies it). */
static inline void feedforward(double t, const double *P, Tab T, double *r, double *i_ff, double *w_ff)
{
    double rr, rd, rdd, ra, rda, rdda;
    reference_rates(t, P, &rr, &rd, &rdd);
    double wf = 0.0;
    if (P[FF_SPEED] > 0.0) {
        long kc;
        double tc, n, dn;
        cell(P, rr, &kc, &tc);
        interp(T, T_N, kc, tc, P[TAB_H], P[INV_H], &n, &dn);
        wf = n * rd;
    }
    reference_rates(t + P[FF_LEAD], P, &ra, &rda, &rdda);
    *r = rr;
    *i_ff = feedforward_current(ra, rda, rdda, P, T);
    *w_ff = wf;
}

#endif
