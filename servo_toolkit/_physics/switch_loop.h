/* The RK4 step split at every friction switch located within it, at any node carrying friction
   that holds: the motor side and the load (first_switch, split_step.h) and the full chain's
   intermediate nodes (node_first_switch, node_switch.h).

   The fixed-step loop (integrate.h, rk4) hands a step to switched_step when its test sees a
   node switch within it (ends: the motor side or the load, switch_ahead or a stage that left a
   direction; mask: the intermediate nodes, node_flags). The step integrates RK4 to the earliest
   of the flagged nodes' switches (each located along its own continued or held motion; with
   more than one flagged, each is located and the earliest kept), and takes the rest of the step
   as a step of its own, checked by the same tests (rk4_checked for the motor side and the load,
   node_flags on its stages' slopes) and split again where a switch falls within it, up to
   MAX_SWITCHES switches, after which the rest is one plain RK4 step. So two switches within one
   step, at any two nodes, keep RK4's fourth order on the smooth stretches between them. */
#ifndef SERVO_SWITCH_LOOP_H
#define SERVO_SWITCH_LOOP_H

#include <stdint.h>

#include "common.h"
#include "node_switch.h"
#include "split_step.h"

/* The switch of candidate c within the step: c < 0 the motor side or the load, else the
   intermediate node c. Returns split; *out, *tau_out and *held_out as node_first_switch. */
static inline int _locate(long c, double t, double dt, double p, double pd, double q, double qd, double cur,
                          double xi, double s, const double *P, long n_par, Tab T, double iref, int cont, int rigid,
                          double *x, long nx, double *xs, double *k1, double *k2, double *k3, double *k4,
                          double pd_new, double qd_new, double *x0, double *PW, long pw_stride, PhysState *out,
                          double *tau_out, int *held_out)
{
    if (c < 0) {
        *held_out = 0;
        return first_switch(t, dt, p, pd, q, qd, cur, xi, s, P, n_par, T, iref, cont, rigid, x, nx, xs, k1, k2, k3,
                            k4, pd_new, qd_new, x0, PW, pw_stride, out, tau_out);
    }
    return node_first_switch(t, dt, p, pd, q, qd, cur, xi, s, P, n_par, T, iref, x, nx, xs, k1, k2, k3, k4, x0, PW,
                             pw_stride, c, out, tau_out, held_out);
}

/* The earliest switch among the candidates (ends, mask: switched_step), as _locate returns it;
   with none splitting, the first candidate's step. x[7:] at the step's start is kept in PW[3]
   while more than one is located. */
static inline int _earliest(double t, double dt, double p, double pd, double q, double qd, double cur, double xi,
                            double s, const double *P, long n_par, Tab T, double iref, int cont, int rigid,
                            double *x, long nx, double *xs, double *k1, double *k2, double *k3, double *k4,
                            double pd_new, double qd_new, double *x0, double *PW, long pw_stride, int ends,
                            int64_t mask, PhysState *out, double *tau_out, int *held_out)
{
    long first = -2, count = 0;
    if (ends) {
        first = -1;
        count = 1;
    }
    int64_t m = mask;
    long j = 0;
    while (m) {
        if (m & 1) {
            if (first == -2)
                first = j;
            count += 1;
        }
        m >>= 1;
        j += 1;
    }
    if (count == 1)
        return _locate(first, t, dt, p, pd, q, qd, cur, xi, s, P, n_par, T, iref, cont, rigid, x, nx, xs, k1, k2,
                       k3, k4, pd_new, qd_new, x0, PW, pw_stride, out, tau_out, held_out);
    double *start = PW + 3 * pw_stride;
    for (long n = 0; n < nx; n++)
        start[n] = x[n];
    long best = first, last = -2;
    double best_tau = 2.0 * dt;
    int split = 0;
    long c = ends ? -1 : 0;
    while (c < 0 || (mask >> c) != 0) {
        if (c < 0 || ((mask >> c) & 1)) {
            for (long n = 0; n < nx; n++)
                x[n] = start[n];
            split = _locate(c, t, dt, p, pd, q, qd, cur, xi, s, P, n_par, T, iref, cont, rigid, x, nx, xs, k1, k2, k3,
                            k4, pd_new, qd_new, x0, PW, pw_stride, out, tau_out, held_out);
            last = c;
            if (split && *tau_out < best_tau) {
                best = c;
                best_tau = *tau_out;
            }
        }
        c += 1;
    }
    if (best == last)
        return split;
    for (long n = 0; n < nx; n++)
        x[n] = start[n];
    return _locate(best, t, dt, p, pd, q, qd, cur, xi, s, P, n_par, T, iref, cont, rigid, x, nx, xs, k1, k2, k3, k4,
                   pd_new, qd_new, x0, PW, pw_stride, out, tau_out, held_out);
}

/* The step from t of nodes that may switch within it, split at the switches located within it
   (file comment). ends: the motor side or the load may switch (pd_new, qd_new: their speeds at
   the plain step's end); mask: the intermediate nodes that may (bits, node_flags), k1..k4
   holding the plain step's slopes. Returns the step's new (p, pd, q, qd, cur, xi) (x[7:]
   advanced in place when they move). x0 (the size of x) and PW (4 rows of pw_stride, each at
   least the size of P and of x) are scratch: the step allocates nothing. */
static inline PhysState switched_step(double t, double dt, double p, double pd, double q, double qd, double cur,
                                      double xi, double s, const double *P, long n_par, Tab T, double iref, int cont,
                                      int rigid, double *x, long nx, double *xs, double *k1, double *k2, double *k3,
                                      double *k4, double pd_new, double qd_new, double *x0, double *PW,
                                      long pw_stride, int ends, int64_t mask)
{
    long n = 0;
    for (;;) {
        PhysState r;
        double tau;
        int held;
        int split = _earliest(t, dt, p, pd, q, qd, cur, xi, s, P, n_par, T, iref, cont, rigid, x, nx, xs, k1, k2,
                              k3, k4, pd_new, qd_new, x0, PW, pw_stride, ends, mask, &r, &tau, &held);
        if (!split)
            return r;
        set_state(r, &p, &pd, &q, &qd, &cur, &xi);
        n += 1;
        t += tau;
        dt -= tau;
        for (long j = 0; j < nx; j++) /* x[7:] at the switch, should the rest be split again */
            x0[j] = x[j];
        /* the rest of the step: with the parameters the switch left (an intermediate node leaving
           rest: its friction held in the direction it leaves to) */
        const double *W = held ? PW : P;
        PhysState r1 = rk4_checked(t, dt, p, pd, q, qd, cur, xi, s, W, T, iref, cont, rigid, x, nx, xs, k1, k2, k3,
                                   k4, &ends);
        mask = node_flags(x0, k1, k2, k3, k4, dt / 6.0, P);
        if (!(ends || mask) || n >= MAX_SWITCHES)
            return r1;
        for (long j = 0; j < nx; j++)
            x[j] = x0[j];
        pd_new = r1.pd;
        qd_new = r1.qd;
    }
}

#endif
