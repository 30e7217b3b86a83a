/* RK4 steps split at friction's switches, located to high order within the step (the motor
   side and the load; the full chain's intermediate nodes in node_switch.h).

   Friction that holds (friction.h) switches where a node carrying it reverses its speed
   (it stops: stick or slide on the other way) and where a stuck node breaks away (the moment
   on it reaches the breakaway level). The right-hand side jumps there, so a step across a
   switch is of low order; the fixed-step loop (integrate.h, rk4) hands such a step to
   switched_step (switch_loop.h), whose locator for the motor side and the load (first_switch)
   finds the switch's instant tau within the step and integrates RK4 to it and from it:

   - a reversal: tau is the zero of the node's speed along the motion continued smoothly past
     it (its sliding friction held at its direction before the zero: DIR_M, DIR_L in a scratch
     copy of the parameters), found by the Illinois method on RK4 trial steps from the step's
     start, each of RK4's own order on that smooth motion (the motor side and the load both
     reversing along it: the earlier of their zeros); the node restarts at rest exactly at tau,
     where the friction decides between stick and slip;
   - a breakaway: tau is where the node's signed breakaway distance crosses 0, along the motion
     with the node held (its breakaway level out of reach in the scratch copy), the distance
     read by the right-hand side with HOLD_GAUGE = 1 in another (friction.h, gear_at_rest:
     for the motor side of a lossy gear, how far the torques on the gear are beyond its band,
     asymmetric with the efficiencies; for a node without one, |moment| less its level); the
     node stays at rest exactly up to tau.

   A node breaking away at tau (or at a reversal whose moment exceeds the breakaway level)
   leaves rest with the speed SEED in the direction it breaks away to, so the rest of the step
   integrates the sliding law from 0+ (its friction jumps from the law at rest to the sliding
   one at tau, not somewhere among the stages).

   The iteration stops when the bracket is within TAU_TOL of the step, so the switch's instant
   costs no more than RK4's own error; the smooth stretches between switches keep RK4's fourth
   order. Where the continued motion does not switch within the step (a reversal the first
   stage's slope predicted, a stage that crossed a speed's zero or broke away from its estimate
   of the state, when the continued motion does not) that motion is the step.

   After a switch the rest of the step, [t + tau, t + dt], is a step of its own: its plain RK4
   step (rk4_checked) is checked with the fixed-step loop's own test (switch_ahead from its
   first stage's slopes and its result, stage_turns on its stages; the full chain's
   intermediate nodes by node_flags, node_switch.h) and, where a second switch falls within
   it, split again in turn, up to MAX_SWITCHES switches per step (switch_loop.h, for every node
   carrying friction).

   The arrays: x (nx states; x[7:] the controller's and the full chain's), xs, k1..k4, x0 (nx
   each: the stages' state and slopes, x[7:] at the step's start); P has n_par slots; PW is 4
   rows of pw_stride (>= n_par, >= nx) doubles, the scratch parameter copies this file writes. */
#ifndef SERVO_SPLIT_STEP_H
#define SERVO_SPLIT_STEP_H

#include "common.h"
#include "rhs.h"

/* TAU_TOL, MAX_ITER, MAX_SWITCHES, HELD and SEED are in layout.h (servo_toolkit/sim/layout.py) */

/* The physical states a step advances (x[0:6]; the play state s is frozen over a step). */
typedef struct {
    double p, pd, q, qd, cur, xi;
} PhysState;

/* The loop's scalars of the physical state set from r. */
static inline void set_state(PhysState r, double *p, double *pd, double *q, double *qd, double *cur, double *xi)
{
    *p = r.p;
    *pd = r.pd;
    *q = r.q;
    *qd = r.qd;
    *cur = r.cur;
    *xi = r.xi;
}

/* Classical RK4's stage k = 0..3: it evaluates at t + c_k from the state advanced by c_k times
   the previous stage's slopes, which enter the update with weight w_k (of dt / 6). */
static inline void rk4_coefficients(long stage, double dt, double *c, double *w)
{
    *c = stage == 0 ? 0.0 : (stage == 3 ? dt : 0.5 * dt);
    *w = (stage == 1 || stage == 2) ? 2.0 : 1.0;
}

/* Whether an RK4 stage's speeds left a node's direction at the step's start (its friction
   then jumped within the step). */
static inline int stage_turns(double pd, double pd_stage, double qd, double qd_stage)
{
    return pd * pd_stage < 0.0 || qd * qd_stage < 0.0;
}

/* One classical RK4 step of length h from the physical state given as scalars (a continuous
   controller's and the full chain's states x[7:] are advanced in place), shared by the steps
   split at friction's switches (_rk4_scalars) and the substeps through the smooth signs' band
   (integrate.h, refined_step). Returns the advanced (p, pd, q, qd, cur, xi), then (out
   pointers, when track) the first stage's slopes of the node speeds and whether a later
   stage's speeds left a node's direction at the step's start (stage_turns). inlined (a
   constant at each call): the right-hand side inlined with the continuous controller's command
   kept in cmd between stages that share their time (rhs_phys_inline), else the out-of-line
   rhs_phys. */
ST_ALWAYS_INLINE PhysState rk4_stages(double t, double h, double p, double pd, double q, double qd, double cur,
                                      double xi, double s, const double *P, Tab T, double iref, int cont, double *x,
                                      long nx, double *xs, double *k1, double *k2, double *k3, double *k4,
                                      double *cmd, int inlined, int track, double *g1_out, double *g3_out,
                                      int *turned_out)
{
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0, s4 = 0.0, s5 = 0.0;
    double u0 = 0.0, u1 = 0.0, u2 = 0.0, u3 = 0.0, u4 = 0.0, u5 = 0.0;
    double g1 = 0.0, g3 = 0.0;
    int turned = 0;
    double d[10];
    for (long stage = 0; stage < 4; stage++) {
        double c, w;
        rk4_coefficients(stage, h, &c, &w);
        double *kout = stage == 0 ? k1 : (stage == 1 ? k2 : (stage == 2 ? k3 : k4));
        if (cont && stage > 0) {
            const double *kin = stage == 1 ? k1 : (stage == 2 ? k2 : k3);
            for (long j = NX_PHYS; j < nx; j++)
                xs[j] = x[j] + c * kin[j];
        }
        if (track && stage > 0)
            turned = turned || stage_turns(pd, pd + c * s1, qd, qd + c * s3);
        if (inlined)
            rhs_phys_inline(t + c, p + c * s0, pd + c * s1, q + c * s2, qd + c * s3, cur + c * s4, xi + c * s5, s,
                            P, T, iref, stage == 0 ? x : xs, kout, d, cmd);
        else
            rhs_phys(t + c, p + c * s0, pd + c * s1, q + c * s2, qd + c * s3, cur + c * s4, xi + c * s5, s,
                     P, T, iref, stage == 0 ? x : xs, kout, d);
        s0 = d[0];
        s1 = d[1];
        s2 = d[2];
        s3 = d[3];
        s4 = d[4];
        s5 = d[5];
        if (stage == 0) {
            g1 = s1;
            g3 = s3;
        }
        u0 += w * s0;
        u1 += w * s1;
        u2 += w * s2;
        u3 += w * s3;
        u4 += w * s4;
        u5 += w * s5;
    }
    double sixth = h / 6.0;
    if (cont)
        for (long j = NX_PHYS; j < nx; j++)
            x[j] += sixth * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
    if (track) {
        *g1_out = g1;
        *g3_out = g3;
        *turned_out = turned;
    }
    PhysState r = {p + sixth * u0, pd + sixth * u1, q + sixth * u2, qd + sixth * u3, cur + sixth * u4,
                   xi + sixth * u5};
    return r;
}

/* rk4_stages with the out-of-line right-hand side, tracking the node speeds' slopes and turns:
   called only where a step is split at friction's switches. */
static inline PhysState _rk4_scalars(double t, double h, double p, double pd, double q, double qd, double cur,
                                     double xi, double s, const double *P, Tab T, double iref, int cont,
                                     double *x, long nx, double *xs, double *k1, double *k2, double *k3,
                                     double *k4, double *g1_out, double *g3_out, int *turned_out)
{
    return rk4_stages(t, h, p, pd, q, qd, cur, xi, s, P, T, iref, cont, x, nx, xs, k1, k2, k3, k4, NULL, 0, 1,
                      g1_out, g3_out, turned_out);
}

/* One classical RK4 step (_rk4_scalars); returns the advanced (p, pd, q, qd, cur, xi). */
static inline PhysState rk4_step(double t, double h, double p, double pd, double q, double qd, double cur,
                                 double xi, double s, const double *P, Tab T, double iref, int cont, double *x,
                                 long nx, double *xs, double *k1, double *k2, double *k3, double *k4)
{
    double g1, g3;
    int turned;
    return _rk4_scalars(t, h, p, pd, q, qd, cur, xi, s, P, T, iref, cont, x, nx, xs, k1, k2, k3, k4, &g1, &g3,
                        &turned);
}

/* Fraction of the step where a speed v reaches 0: from the first stage's slope (its linear
   prediction v_lin at the step's end), else from the step's result v_new; 1.0 for none. RK4's
   later stages straddle the friction's jump and may hide a reversal from the result (the stages
   on the far side push the speed back), so the slope at the step's start decides first. */
static inline double _crossing(double v, double v_new, double v_lin)
{
    if (v * v_lin < 0.0)
        return v / (v - v_lin);
    if (v * v_new < 0.0)
        return v / (v - v_new);
    return 1.0;
}

/* Where within the step a node carrying friction reverses its speed: the fraction of the step
   (1.0: no reversal, _crossing) and the node (0 the motor side, 1 the load, -1 none). *_new are
   the step's results, *_lin the speeds its first stage's slopes predict. A speed landing exactly
   on 0 is no reversal: the next step starts at rest. */
static inline double reversal(double pd, double pd_new, double pd_lin, double qd, double qd_new, double qd_lin,
                              const double *P, int rigid, long *node_out)
{
    double frac = 1.0;
    long node = -1;
    if (P[TS_M] > 0.0 || (rigid && P[TS_L] > 0.0)) {
        frac = _crossing(pd, pd_new, pd_lin);
        node = frac < 1.0 ? 0 : -1;
    }
    if (!rigid && P[TS_L] > 0.0) {
        double f = _crossing(qd, qd_new, qd_lin);
        if (f < frac) {
            frac = f;
            node = 1;
        }
    }
    *node_out = node;
    return frac;
}

/* Whether a node carrying friction may switch within the step: reverses (reversal) or, at rest
   at the step's start, moves at its end (a breakaway). Cheap, in the step loop (which also
   hands over a step one of whose stages left a node's direction: stage_turns); switched_step
   then decides and does the work. */
static inline int switch_ahead(double pd, double pd_new, double pd_lin, double qd, double qd_new, double qd_lin,
                               const double *P, int rigid)
{
    long node;
    double frac = reversal(pd, pd_new, pd_lin, qd, qd_new, qd_lin, P, rigid, &node);
    if (frac < 1.0)
        return 1;
    if (pd == 0.0 && pd_new != 0.0 && (P[TS_M] > 0.0 || (rigid && P[TS_L] > 0.0)))
        return 1;
    return !rigid && qd == 0.0 && qd_new != 0.0 && P[TS_L] > 0.0;
}

/* rk4_step that also tells (*ahead) whether a node carrying friction may switch within the step,
   by the fixed-step loop's own test: switch_ahead from the first stage's slopes and the result,
   or a stage whose speed left a node's direction (stage_turns). */
static inline PhysState rk4_checked(double t, double h, double p, double pd, double q, double qd, double cur,
                                    double xi, double s, const double *P, Tab T, double iref, int cont, int rigid,
                                    double *x, long nx, double *xs, double *k1, double *k2, double *k3, double *k4,
                                    int *ahead)
{
    double g1, g3;
    int turned;
    PhysState r = _rk4_scalars(t, h, p, pd, q, qd, cur, xi, s, P, T, iref, cont, x, nx, xs, k1, k2, k3, k4, &g1,
                               &g3, &turned);
    *ahead = turned || switch_ahead(pd, r.pd, pd + h * g1, qd, r.qd, qd + h * g3, P, rigid);
    return r;
}

/* An RK4 step of length h from the step's start with the parameters W (x[7:] restored from x0
   first when they move). */
static inline PhysState _trial(double t, double h, double p, double pd, double q, double qd, double cur, double xi,
                               double s, const double *W, Tab T, double iref, int cont, double *x, long nx,
                               const double *x0, double *xs, double *k1, double *k2, double *k3, double *k4)
{
    if (cont)
        for (long j = NX_PHYS; j < nx; j++)
            x[j] = x0[j];
    return rk4_step(t, h, p, pd, q, qd, cur, xi, s, W, T, iref, cont, x, nx, xs, k1, k2, k3, k4);
}

/* The held node's signed breakaway distance over its inertia (Z: HOLD_GAUGE = 1) after a step of
   length h with the node held at rest. */
static inline double _held_moment(double t, double h, double p, double pd, double q, double qd, double cur,
                                  double xi, double s, const double *H, const double *Z, Tab T, double iref,
                                  int cont, double *x, long nx, const double *x0, double *xs, double *k1,
                                  double *k2, double *k3, double *k4, long node)
{
    PhysState r = _trial(t, h, p, pd, q, qd, cur, xi, s, H, T, iref, cont, x, nx, x0, xs, k1, k2, k3, k4);
    double d[10];
    rhs_phys(t + h, r.p, r.pd, r.q, r.qd, r.cur, r.xi, s, Z, T, iref, x, k1, d);
    return node == 0 ? d[1] : d[3];
}

/* The Illinois method's next trial on [a, b] (g(a) g(b) < 0): returns closed, once the bracket
   is within TAU_TOL of b (the search ends there, *c = b), else *c the secant's zero (the
   midpoint when it falls outside the bracket). */
static inline int illinois_trial(double a, double b, double ga, double gb, double *c)
{
    if (b - a <= TAU_TOL * (b > 0.0 ? b : 1.0)) {
        *c = b;
        return 1;
    }
    double cc = b - gb * (b - a) / (gb - ga);
    if (!(a < cc && cc < b))
        cc = 0.5 * (a + b);
    *c = cc;
    return 0;
}

/* The Illinois method's bracket after a trial c with value gc: c replaces the end whose value
   has gc's sign, and the other end's value is halved when the same end is replaced twice
   running (side: the end replaced last, 1 for b, -1 for a, 0 before any). Updates
   (a, b, ga, gb, side) in place. */
static inline void illinois_next(double *a, double *b, double *ga, double *gb, double c, double gc, long *side)
{
    if ((gc > 0.0) == (*gb > 0.0)) {
        *ga = *side == 1 ? 0.5 * *ga : *ga;
        *b = c;
        *gb = gc;
        *side = 1;
        return;
    }
    *gb = *side == -1 ? 0.5 * *gb : *gb;
    *a = c;
    *ga = gc;
    *side = -1;
}

/* The zero of g on [a, b] (g(a) g(b) < 0) by the Illinois method: g the node's speed after a
   trial step with W (a reversal), else the held node's breakaway distance (a breakaway,
   _held_moment). */
static inline double _illinois(double a, double b, double ga, double gb, double t, double p, double pd, double q,
                               double qd, double cur, double xi, double s, const double *W, const double *H,
                               const double *Z, Tab T, double iref, int cont, double *x, long nx, const double *x0,
                               double *xs, double *k1, double *k2, double *k3, double *k4, long node, int breakaway)
{
    long side = 0;
    for (long it = 0; it < MAX_ITER; it++) {
        double c, gc;
        if (illinois_trial(a, b, ga, gb, &c))
            break;
        if (breakaway) {
            gc = _held_moment(t, c, p, pd, q, qd, cur, xi, s, H, Z, T, iref, cont, x, nx, x0, xs, k1, k2, k3, k4,
                              node);
        } else {
            PhysState r = _trial(t, c, p, pd, q, qd, cur, xi, s, W, T, iref, cont, x, nx, x0, xs, k1, k2, k3, k4);
            gc = node == 0 ? r.pd : r.qd;
        }
        if (gc == 0.0)
            return c;
        illinois_next(&a, &b, &ga, &gb, c, gc, &side);
    }
    return breakaway ? a : b; /* a breakaway: still held at a; a reversal: just past the zero */
}

/* The first switch within the step from t (module comment): returns 1 with *out the state at
   t + tau just after it (RK4 to tau, the node at rest there or leaving it; x[7:] advanced to
   t + tau), else 0 with the step's result (the continued motion, or the node held all through)
   and tau = dt. */
static inline int first_switch(double t, double dt, double p, double pd, double q, double qd, double cur,
                               double xi, double s, const double *P, long n_par, Tab T, double iref, int cont,
                               int rigid, double *x, long nx, double *xs, double *k1, double *k2, double *k3,
                               double *k4, double pd_new, double qd_new, double *x0, double *PW, long pw_stride,
                               PhysState *out, double *tau_out)
{
    for (long j = 0; j < nx; j++)
        x0[j] = x[j];
    int load = !rigid && P[TS_L] > 0.0; /* the load carries friction of its own */
    int motor = P[TS_M] > 0.0 || (rigid && P[TS_L] > 0.0);
    long node = -1;
    if (motor && pd == 0.0 && pd_new != 0.0)
        node = 0;
    else if (load && qd == 0.0 && qd_new != 0.0)
        node = 1;
    int breakaway = node >= 0;
    double *W = PW, *H = PW + pw_stride, *Z = PW + 2 * pw_stride;
    for (long j = 0; j < n_par; j++) {
        /* the trial parameters: a reversing node's friction held at its direction (W); a
           breakaway: the node held at rest (H), the node's breakaway distance (then its side)
           in place of its acceleration (Z) */
        W[j] = H[j] = Z[j] = P[j];
    }
    Z[HOLD_GAUGE] = 1.0;
    double tau = 0.0;
    PhysState r;
    if (!breakaway) {
        double g0, g1;
        W[DIR_M] = pd == 0.0 ? 0.0 : (pd > 0.0 ? 1.0 : -1.0);
        W[DIR_L] = (rigid || qd == 0.0) ? 0.0 : (qd > 0.0 ? 1.0 : -1.0);
        r = _trial(t, dt, p, pd, q, qd, cur, xi, s, W, T, iref, cont, x, nx, x0, xs, k1, k2, k3, k4);
        if (motor && pd * r.pd < 0.0) {
            node = 0;
            g0 = pd;
            g1 = r.pd;
        } else if (load && qd * r.qd < 0.0) {
            node = 1;
            g0 = qd;
            g1 = r.qd;
        } else { /* the continued motion does not reverse within the step: it is the step (a stage
                    of the plain step that crossed a speed's zero made the friction jump there) */
            *out = r;
            *tau_out = dt;
            return 0;
        }
        tau = _illinois(0.0, dt, g0, g1, t, p, pd, q, qd, cur, xi, s, W, H, Z, T, iref, cont, x, nx, x0, xs, k1, k2,
                        k3, k4, node, 0);
        if (node == 0 && load && qd * r.qd < 0.0) { /* both reverse along the continued motion: the earlier */
            double tau_l = _illinois(0.0, dt, qd, r.qd, t, p, pd, q, qd, cur, xi, s, W, H, Z, T, iref, cont, x, nx,
                                     x0, xs, k1, k2, k3, k4, 1, 0);
            if (tau_l < tau) {
                tau = tau_l;
                node = 1;
            }
        }
    } else {
        if (node == 0)
            H[TS_M] = HELD;
        else
            H[TS_L] = HELD;
        double g1 = _held_moment(t, dt, p, pd, q, qd, cur, xi, s, H, Z, T, iref, cont, x, nx, x0, xs, k1, k2, k3,
                                 k4, node);
        if (g1 <= 0.0) { /* held at the step's end: at rest all through it (a stage of the plain
                            step, from its estimate of the state, broke away too early) */
            *out = _trial(t, dt, p, pd, q, qd, cur, xi, s, H, T, iref, cont, x, nx, x0, xs, k1, k2, k3, k4);
            *tau_out = dt;
            return 0;
        }
        double g0 = _held_moment(t, 0.0, p, pd, q, qd, cur, xi, s, H, Z, T, iref, cont, x, nx, x0, xs, k1, k2, k3,
                                 k4, node);
        if (g0 < 0.0)
            tau = _illinois(0.0, dt, g0, g1, t, p, pd, q, qd, cur, xi, s, W, H, Z, T, iref, cont, x, nx, x0, xs, k1,
                            k2, k3, k4, node, 1);
    }
    /* RK4 to tau (the continued motion, or held at rest), the node at rest there */
    r = _trial(t, tau, p, pd, q, qd, cur, xi, s, breakaway ? H : W, T, iref, cont, x, nx, x0, xs, k1, k2, k3, k4);
    set_state(r, &p, &pd, &q, &qd, &cur, &xi);
    if (node == 0) {
        pd = 0.0;
        if (rigid)
            qd = 0.0;
    } else {
        qd = 0.0;
    }
    double d[10], slide;
    if (breakaway) { /* the side it breaks away to, at tau */
        Z[HOLD_GAUGE] = 2.0;
        rhs_phys(t + tau, p, pd, q, qd, cur, xi, s, Z, T, iref, x, k1, d);
        slide = node == 0 ? d[1] : d[3];
    } else { /* at rest at the reversal: stuck, or breaking away the other way at once */
        rhs_phys(t + tau, p, pd, q, qd, cur, xi, s, P, T, iref, x, k1, d);
        slide = node == 0 ? d[1] : d[3];
    }
    if (slide != 0.0) {
        /* breaking away: the node leaves rest sliding (SEED in the moment's direction), so every
           stage of the rest of the step sees the sliding friction at 0+ (Ts on the Stribeck
           curve, Tc at once without a Stribeck speed), not the law at rest */
        double v = slide > 0.0 ? SEED : -SEED;
        if (node == 0) {
            pd = v;
            if (rigid)
                qd = v;
        } else {
            qd = v;
        }
    }
    PhysState o = {p, pd, q, qd, cur, xi};
    *out = o;
    *tau_out = tau;
    return 1;
}

#endif
