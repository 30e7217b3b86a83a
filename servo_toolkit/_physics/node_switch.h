/* RK4 steps split at the switches of the full chain's intermediate nodes' friction (called by
   switched_step, switch_loop.h, at a switch only).

   An intermediate node carrying a stage's friction (NODE_FRIC, node_friction) switches where it
   reverses its speed and where, stuck, the moment on it reaches its breakaway level, as the
   motor side and the load do (split_step.h, whose RK4 trial steps this file calls). The
   fixed-step loop (integrate.h, rk4) hands a step to switched_step (switch_loop.h) when
   node_flags sees a node carrying friction leave its direction within the step (at its end, at
   one of RK4's stages, or along the first stage's slope) or leave rest; node_first_switch finds
   the node's switch instant tau within the step and integrates RK4 to it:

   - a reversal: tau is the zero of the node's speed along the motion continued past it (its
     sliding friction held at its direction before the zero: the node's NF_DIR in a scratch copy
     of the parameters), by the Illinois method on RK4 trial steps from the step's start; the
     node restarts at rest exactly at tau, where its stick law decides;
   - a breakaway: tau is where the moment on the node held at rest (its breakaway level out of
     reach) reaches its breakaway level, the moment read with the level at 0.

   A node leaving rest at tau does so with the speed SEED in the moment's direction, its friction
   held at that direction for the rest of the step, so the rest of the step integrates its
   sliding law from 0+ (the breakaway's instant is the first past the level, so the moment there
   drives the node the way it leaves). The bracket is closed to TAU_TOL of the step, so the
   smooth stretches between switches keep RK4's fourth order. The rest of the step is checked
   and split again like the motor side's and the load's (switch_loop.h: every switch within a
   step at any node, the earliest of several flagged ones first). */
#ifndef SERVO_NODE_SWITCH_H
#define SERVO_NODE_SWITCH_H

#include <stdint.h>

#include "common.h"
#include "rhs.h"
#include "split_step.h"

/* the intermediate nodes whose switches are located within a step (bits of an int64) */
#define MAX_FLAGGED 62

/* Whether intermediate node j (0 the first) carrying friction may switch within the step whose
   stages' slopes are k1..k4 (x[7:] still at the step's start): its speed leaves its direction
   at the step's end, at a stage or along the first stage's slope, or leaves rest. */
static inline int node_flag(const double *x, const double *k1, const double *k2, const double *k3,
                            const double *k4, double sixth, const double *P, long j)
{
    if (P[IX(P[NODE_FRIC]) + NF_STRIDE * j + NF_TS] <= 0.0)
        return 0;
    long i = IX(P[OFF_NODE]) + 2 * j + 1;
    double h = 6.0 * sixth;
    double v0 = x[i];
    double v1 = v0 + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    if (v0 == 0.0)
        return v1 != 0.0;
    return (v1 * v0 <= 0.0 || (v0 + h * k1[i]) * v0 < 0.0 || (v0 + 0.5 * h * k2[i]) * v0 < 0.0
            || (v0 + h * k3[i]) * v0 < 0.0);
}

/* The intermediate nodes that may switch within the step (node_flag) as bits (bit j: node j;
   the first MAX_FLAGGED nodes), 0 for none or without friction at intermediate nodes. */
static inline int64_t node_flags(const double *x, const double *k1, const double *k2, const double *k3,
                                 const double *k4, double sixth, const double *P)
{
    int64_t mask = 0;
    if (P[NODE_FRIC] > 0.0) {
        long n = IX(P[NMID]);
        if (n > MAX_FLAGGED)
            n = MAX_FLAGGED;
        for (long j = 0; j < n; j++)
            if (node_flag(x, k1, k2, k3, k4, sixth, P, j))
                mask |= (int64_t)1 << j;
    }
    return mask;
}

/* The switch function at tau: the node's speed after a trial step of length tau with W (a
   reversal), or |its held moment| - cap after a trial step with the node held (W = H; a
   breakaway: the moment as an acceleration, read with Z). */
static inline double _node_g(double tau, double t, double p, double pd, double q, double qd, double cur,
                             double xi, double s, const double *W, const double *Z, Tab T, double iref, double *x,
                             long nx, const double *x0, double *xs, double *k1, double *k2, double *k3, double *k4,
                             long i, int breakaway, double cap)
{
    PhysState r = _trial(t, tau, p, pd, q, qd, cur, xi, s, W, T, iref, 1, x, nx, x0, xs, k1, k2, k3, k4);
    if (!breakaway)
        return x[i];
    double d[10];
    rhs_phys(t + tau, r.p, r.pd, r.q, r.qd, r.cur, r.xi, s, Z, T, iref, x, k1, d);
    return fabs(k1[i]) - cap;
}

/* The zero of _node_g on [a, b] (ga gb < 0) by the Illinois method: the first instant past it
   (a breakaway: the moment beyond the level, so the node leaves rest in its direction; a
   reversal: just past the speed's zero). */
static inline double _node_illinois(double a, double b, double ga, double gb, double t, double p, double pd,
                                    double q, double qd, double cur, double xi, double s, const double *W,
                                    const double *Z, Tab T, double iref, double *x, long nx, const double *x0,
                                    double *xs, double *k1, double *k2, double *k3, double *k4, long i,
                                    int breakaway, double cap)
{
    long side = 0;
    for (long it = 0; it < MAX_ITER; it++) {
        double c;
        if (illinois_trial(a, b, ga, gb, &c))
            break;
        double gc = _node_g(c, t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, nx, x0, xs, k1, k2, k3, k4, i,
                            breakaway, cap);
        if (gc == 0.0)
            return c;
        illinois_next(&a, &b, &ga, &gb, c, gc, &side);
    }
    return b; /* a breakaway: the first instant beyond the level; a reversal: just past the zero */
}

/* The switch of intermediate node j within the step from t (module comment): returns 1 with *out
   the state at t + tau just after it (RK4 to tau, the node at rest there or leaving it, x[7:]
   advanced to t + tau; *held: it leaves rest, and the rest of the step takes the parameters
   PW[0], its friction held in that direction), else 0 with the step's result (the continued
   motion, or the node held all through), tau = dt. x0 (the size of x) and PW (2 rows of
   pw_stride >= n_par) are scratch. */
static inline int node_first_switch(double t, double dt, double p, double pd, double q, double qd, double cur,
                                    double xi, double s, const double *P, long n_par, Tab T, double iref, double *x,
                                    long nx, double *xs, double *k1, double *k2, double *k3, double *k4, double *x0,
                                    double *PW, long pw_stride, long j, PhysState *out, double *tau_out,
                                    int *held_out)
{
    for (long m = 0; m < nx; m++)
        x0[m] = x[m];
    long slot = IX(P[NODE_FRIC]) + NF_STRIDE * j;
    long i = IX(P[OFF_NODE]) + 2 * j + 1;
    double v0 = x0[i];
    int breakaway = v0 == 0.0;
    /* a reversal: the node's friction held at its direction (W); a breakaway: the node held (W),
       the moment on the node read with its level at 0 (Z) */
    double *W = PW, *Z = PW + pw_stride;
    for (long m = 0; m < n_par; m++)
        W[m] = Z[m] = P[m];
    double tau = 0.0, cap = 0.0, a1 = 0.0;
    double d[10];
    PhysState r;
    *held_out = 0;
    if (!breakaway) {
        W[slot + NF_DIR] = v0 > 0.0 ? 1.0 : -1.0;
        r = _trial(t, dt, p, pd, q, qd, cur, xi, s, W, T, iref, 1, x, nx, x0, xs, k1, k2, k3, k4);
        if (x[i] * v0 >= 0.0) { /* the continued motion does not reverse within the step: it is the step */
            *out = r;
            *tau_out = dt;
            return 0;
        }
        tau = _node_illinois(0.0, dt, v0, x[i], t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, nx, x0, xs, k1, k2,
                             k3, k4, i, 0, 0.0);
    } else {
        W[slot + NF_TS] = HELD;
        Z[slot + NF_TS] = 0.0;
        r = _trial(t, dt, p, pd, q, qd, cur, xi, s, W, T, iref, 1, x, nx, x0, xs, k1, k2, k3, k4);
        rhs_phys(t + dt, r.p, r.pd, r.q, r.qd, r.cur, r.xi, s, Z, T, iref, x, k1, d);
        a1 = k1[i];
        rhs_phys(t + dt, r.p, r.pd, r.q, r.qd, r.cur, r.xi, s, P, T, iref, x, k1, d);
        double broken = k1[i];
        if (broken == 0.0) { /* held at the step's end: at rest all through it */
            *out = r;
            *tau_out = dt;
            return 0;
        }
        cap = fabs(a1 - broken); /* the breakaway level as an acceleration */
        double g0 = _node_g(0.0, t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, nx, x0, xs, k1, k2, k3, k4, i, 1,
                            cap);
        if (g0 < 0.0)
            tau = _node_illinois(0.0, dt, g0, fabs(a1) - cap, t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, nx, x0,
                                 xs, k1, k2, k3, k4, i, 1, cap);
    }
    /* RK4 to tau (the continued motion, or held at rest), the node at rest there */
    r = _trial(t, tau, p, pd, q, qd, cur, xi, s, W, T, iref, 1, x, nx, x0, xs, k1, k2, k3, k4);
    x[i] = 0.0;
    double slide;
    if (breakaway) {
        slide = a1;
    } else { /* at rest at the reversal: stuck, or breaking away the other way at once */
        rhs_phys(t + tau, r.p, r.pd, r.q, r.qd, r.cur, r.xi, s, P, T, iref, x, k1, d);
        slide = k1[i];
    }
    *out = r;
    *tau_out = tau;
    if (slide == 0.0) /* stuck */
        return 1;
    /* breaking away: the node leaves rest sliding (SEED in the moment's direction, its friction
       held at that direction for the rest of the step), so every stage sees the sliding law from 0+ */
    for (long m = 0; m < n_par; m++)
        W[m] = P[m];
    W[slot + NF_DIR] = slide > 0.0 ? 1.0 : -1.0;
    x[i] = slide > 0.0 ? SEED : -SEED;
    *held_out = 1;
    return 1;
}

#endif
