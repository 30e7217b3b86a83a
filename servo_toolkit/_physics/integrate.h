/* The fixed-step loops: classical RK4 and the cam paper's discrete scheme (seed 002); their
   Python driver, which runs them chunk by chunk, is servo_toolkit.sim.integrators.integrate.

   RK4 with the smooth friction (no stick) splits a step whose motor speed passes through the
   band of its smooth sign tanh(omega_m / w_s) into substeps (smooth_substeps): there the
   smooth Coulomb friction and the drivetrain's loss switch within a fraction of a
   millisecond, and at a step of 0.1 ms their switch, not the smooth motion between reversals,
   made nearly all of a run's error. With friction that holds the switches are located instead
   (split_step.h, switch_loop.h).

   Both loops hold the sampled controller's output between samples (zero-order hold), sample it
   every sub steps, record every rec_every steps, track the peak motor torque at every step,
   and stop with a status code on a non-finite state or on the stroke end. No allocation
   happens inside the loop.

   The paper's scheme (seed 002 section 3): over each step the configuration (p, q, the play
   state s) is frozen, the velocities and electrical states take one RK4 step with J(p), N(p)
   and the spring moment frozen, positions follow by summation (p += T p'), and the play
   operator (seed eqs 6-8, c = half the play) updates s. It is first order in T.

   A run is advanced in chunks of steps, one call each (integrators.integrate), so that Ctrl-C
   and SIGTERM, which Python acts on only between calls, end a long run within about CHUNK_S. A
   chunk carries the loop's counters and running figures to the next one (carry, slots C_*)
   and every step's time is t0 + step * dt with the run's own step index, so a run in chunks
   gives the same numbers, bit for bit, as one call.

   2-D arrays are row-major: out_x (rows of nx), out_aux (rows of NAUX), snap (NSNAP rows of
   nx + 2), K (5 rows of nx: the stages' slopes k1..k4 and state xs), PW (4 rows of pw_stride
   >= max(n_par, nx): the split step's parameter copies). */
#ifndef SERVO_INTEGRATE_H
#define SERVO_INTEGRATE_H

#include <stdint.h>

#include "common.h"
#include "control.h"
#include "rhs.h"
#include "split_step.h"
#include "node_switch.h"
#include "switch_loop.h"

/* the carry slots C_* and NCARRY, which a chunk passes to the next, are in layout.h */

/* What a loop returns: (status, step, n_rec, max_tau, iref) in Python. */
typedef struct {
    long status; /* OK, NONFINITE or STROKE_END */
    long step;   /* steps completed (the failing step when not OK) */
    long n_rec;  /* records written */
    double max_tau; /* peak |motor torque| over every step (N*m) */
    double iref;    /* the held current reference at the end (A) */
} LoopResult;

/* One test per step: a NaN or inf anywhere makes the sum non-finite. */
static inline int _finite(const double *x, long nx)
{
    double acc = 0.0;
    for (long j = 0; j < nx; j++)
        acc += x[j];
    return isfinite(acc);
}

/* The physical states x[0:7] written from the loop's scalars into row[0:7]: the state array
   at a sample and at the end, a record's row, a snapshot's row. */
static inline void put_state(double *row, double p, double pd, double q, double qd, double cur, double xi,
                             double s)
{
    row[0] = p;
    row[1] = pd;
    row[2] = q;
    row[3] = qd;
    row[4] = cur;
    row[5] = xi;
    row[6] = s;
}

/* The zero-order hold of the sampled controller: every sub steps (none when 0) the physical
   state is written to x[0:7] and the controller sampled. Updates the held i_ref (*iref) and
   the steps left to the next sample (*to_sample). */
static inline void sample_hold(double t, long sub, long *to_sample, double *iref, double p, double pd, double q,
                               double qd, double cur, double xi, double s, double *x, const double *P, Tab T,
                               double *work)
{
    if (sub > 0) {
        if (*to_sample == 0) {
            put_state(x, p, pd, q, qd, cur, xi, s);
            *iref = controller_sample(t, x, P, T, work);
            *to_sample = sub;
        }
        *to_sample -= 1;
    }
}

/* OK, NONFINITE (one test: a NaN or inf anywhere makes the sum non-finite) or STROKE_END
   (err_mode: the output left the stroke). */
static inline long step_status(double p, double pd, double q, double qd, double cur, double xi, double s,
                               const double *x, long nx, double tau, const double *P, int err_mode, int rigid)
{
    double acc = p + pd + q + qd + cur + xi + s;
    for (long j = NX_PHYS; j < nx; j++)
        acc += x[j];
    if (!isfinite(acc) || !isfinite(tau))
        return NONFINITE;
    double qo = rigid ? p : q;
    if (err_mode && (qo > P[STROKE_HI] || qo < P[STROKE_LO]))
        return STROKE_END;
    return OK;
}

/* Row k of a run's snapshots (rows of nx + 2): the physical state, x[7:], the time and the held
   i_ref. */
static inline void snapshot(double *snap, long k, double p, double pd, double q, double qd, double cur, double xi,
                            double s, const double *x, long nx, double t, double iref)
{
    double *row = snap + k * (nx + 2);
    put_state(row, p, pd, q, qd, cur, xi, s);
    for (long j = NX_PHYS; j < nx; j++)
        row[j] = x[j];
    row[nx] = t;
    row[nx + 1] = iref;
}

/* Whether a run of the smooth friction (no stick) has a smooth sign: the Coulomb torque's or
   the drivetrain loss's, tanh(omega_m / w_s). */
static inline int has_smooth_signs(const double *P)
{
    return !(P[STICK] > 0.0) && (P[TC] > 0.0 || P[ETA_MEAN] > 0.0);
}

/* The largest |N| of the stroke's ratio table: a bound that spares the exact ratio's
   evaluation for a step far from the smooth signs' band. */
static inline double ratio_bound(const double *P, Tab T)
{
    double m = 0.0;
    long n = (long)P[TAB_N];
    for (long k = 0; k < n; k++)
        m = fmax(m, fabs(TAB(T, T_N, k)));
    return m;
}

/* How many RK4 substeps a step of length dt of the smooth friction (no stick) takes (1: the
   step as it is), from the output speed pd at its start and its slope there, pd_dot. A step
   whose motor speed passes through the band of its smooth sign (the speed at the start and at
   the end the slope predicts differ in sign, or the smaller is within SMOOTH_BAND of the
   smoothing speed w_s: tanh(N p' / w_s) has not settled) and moves the sign's argument
   N p' / w_s by more than SMOOTH_RESOLUTION is taken in SMOOTH_SUBSTEPS substeps: there the
   smooth Coulomb friction and the drivetrain's loss switch within a fraction of a
   millisecond. A step fine enough to resolve the band takes it as it is. The number of
   substeps is fixed, so that the steps of a run at dt / 2 are those at dt halved (RK4's
   fourth order holds for the whole scheme). */
static inline long smooth_substeps(const double *P, Tab T, double n_max, double p, double pd, double pd_dot,
                                   double dt)
{
    double pd_new = pd + dt * pd_dot;
    double slow = fmin(fabs(pd), fabs(pd_new));
    if (pd * pd_new > 0.0 && slow * n_max * P[WS] >= SMOOTH_BAND)
        return 1;
    double n, dn;
    hermite(T, T_N, P, p, &n, &dn);
    double an = fabs(n) * P[WS];
    if (pd * pd_new > 0.0 && slow * an >= SMOOTH_BAND)
        return 1;
    return fabs(dt * pd_dot) * an > SMOOTH_RESOLUTION ? SMOOTH_SUBSTEPS : 1;
}

/* The step of length dt from t taken as m classical RK4 steps (m from smooth_substeps):
   rk4_stages with the right-hand side inlined as in the loop and the continuous controller's
   command kept between stages that share their time (cmd, as the loop keeps it). x[7:] (a
   continuous controller's, the full chain's nodes) advance in place. */
ST_NOINLINE PhysState refined_step(long m, double t, double dt, double p, double pd, double q, double qd, double cur,
                                   double xi, double s, const double *P, Tab T, double iref, int cont, double *x,
                                   long nx, double *xs, double *k1, double *k2, double *k3, double *k4, double *cmd)
{
    double h = dt / (double)m;
    PhysState r = {p, pd, q, qd, cur, xi};
    for (long k = 0; k < m; k++)
        r = rk4_stages(t + (double)k * h, h, r.p, r.pd, r.q, r.qd, r.cur, r.xi, s, P, T, iref, cont, x, nx, xs, k1, k2,
                       k3, k4, cmd, 1, 0, NULL, NULL, NULL);
    return r;
}

/* Classical RK4 with the physical states x[0:7] held in local scalars (registers); exported as
   servo_toolkit.sim.integrators._rk4.

   Same arithmetic as the array form (rhs); x[0:7] is written back before each controller
   sample and at the end. The controller and estimator states x[7:] change only at the samples
   unless the motion controller is continuous. Every rec_every steps the state at the step's
   start is recorded; at every step the run's figures (fig, F_*: peak tracking error, current
   and torque, limits reached) and its snapshots (snap, S_*) are kept, so that a figure never
   depends on the record interval.

   The call runs the steps first .. last - 1 of a run of n_steps (and its end, the record and
   the check at n_steps, when last is n_steps); carry (slots C_*) takes the loop's counters and
   running figures from the call before it (none when first is 0: iref is then the held
   current reference) and keeps them for the next. K: 5 rows of nx, zeros (the stages' slopes
   and state); work: the controller's (>= max(nx, 1)); x0: nx; PW: 4 rows of pw_stride. */
static inline LoopResult rk4(double *x, long nx, const double *P, long n_par, Tab T, double t0, double dt,
                             long first, long last, long n_steps, long sub, double iref, long rec_every,
                             double *out_t, double *out_x, double *out_aux, double *fig, double *snap,
                             double *carry, double *K, double *work, double *x0, double *PW, long pw_stride)
{
    double *k1 = K, *k2 = K + nx, *k3 = K + 2 * nx, *k4 = K + 3 * nx, *xs = K + 4 * nx;
    long n_rec = 0;
    double max_tau = 0.0;
    double max_err = 0.0;
    double max_cur = -1.0;
    double max_defl = -1.0;
    double sat = 0.0;
    long to_sample = 0;
    long to_record = 0;
    if (first > 0) {
        iref = carry[C_IREF];
        to_sample = (long)carry[C_TO_SAMPLE];
        to_record = (long)carry[C_TO_RECORD];
        n_rec = (long)carry[C_NREC];
        max_tau = carry[C_MAX_TAU];
        max_err = carry[C_MAX_ERR];
        max_cur = carry[C_MAX_CUR];
        max_defl = carry[C_MAX_DEFL];
        sat = carry[C_SAT];
    }
    long stop = last >= n_steps ? n_steps + 1 : last;
    double ilim = P[ILIM];
    double vlim = P[VLIM];
    int err_mode = P[STROKE_MODE] == 0.0;
    int rigid = P[RIGID] > 0.0;
    /* states in x[7:] that move between samples: a continuous controller's, the full chain's nodes */
    int cont = IX(P[CMODE]) == CONTINUOUS || P[NMID] > 0.0;
    int stick = P[STICK] > 0.0; /* friction that holds: speed reversals are located within the step */
    int lands = stick && P[NODE_FRIC] > 0.0; /* ... at the full chain's intermediate nodes too */
    /* the smooth signs of the Coulomb friction and of the drivetrain's loss: a step through
       their band is taken in substeps (smooth_substeps) */
    int smooth = has_smooth_signs(P);
    double n_max = smooth ? ratio_bound(P, T) : 0.0;
    double p = x[0], pd = x[1], q = x[2], qd = x[3], cur = x[4], xi = x[5], s = x[6];
    long status = OK;
    double sixth = dt / 6.0;
    double g1 = 0.0, g3 = 0.0;
    long step = first;
    double t = t0 + first * dt;
    double d[10];
    /* the continuous controller's command at the last time it was evaluated (rhs_phys_inline's
       cmd); without feedforward it is the reference the step's error check evaluates */
    double cmd[4] = {-INFINITY, 0.0, 0.0, 0.0};
    int shares_ref = IX(P[CMODE]) == CONTINUOUS && !(P[FF_ON] > 0.0);
    for (long it = first; it < stop; it++) {
        step = it;
        t = t0 + step * dt;
        sample_hold(t, sub, &to_sample, &iref, p, pd, q, qd, cur, xi, s, x, P, T, work);
        double r_t = reference(t, P);
        if (shares_ref) {
            cmd[0] = t;
            cmd[1] = r_t;
            cmd[2] = 0.0;
            cmd[3] = 0.0;
        }
        double err = fabs(q - r_t);
        if (err > max_err)
            max_err = err;
        /* stage k evaluates at t + c_k dt from the previous slopes and enters the update with
           weight w_k; the first stage also records and checks */
        double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0, s4 = 0.0, s5 = 0.0;
        double u0 = 0.0, u1 = 0.0, u2 = 0.0, u3 = 0.0, u4 = 0.0, u5 = 0.0;
        int done = 0;
        long m = 1; /* substeps of a step through the smooth signs' band */
        int turned = 0; /* a stage's speed left a node's direction (friction that holds) */
        /* the four stages unrolled: their coefficients and slope rows become constants */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC unroll 4
#endif
        for (long stage = 0; stage < 4; stage++) {
            double c, w;
            rk4_coefficients(stage, dt, &c, &w);
            double *kout = stage == 0 ? k1 : (stage == 1 ? k2 : (stage == 2 ? k3 : k4));
            if (cont && stage > 0) {
                const double *kin = stage == 1 ? k1 : (stage == 2 ? k2 : k3);
                for (long j = NX_PHYS; j < nx; j++)
                    xs[j] = x[j] + c * kin[j];
            }
            if (stick && stage > 0)
                turned = turned || stage_turns(pd, pd + c * s1, qd, qd + c * s3);
            rhs_phys_inline(t + c, p + c * s0, pd + c * s1, q + c * s2, qd + c * s3, cur + c * s4, xi + c * s5, s, P, T,
                     iref, stage == 0 ? x : xs, kout, d, cmd);
            s0 = d[0];
            s1 = d[1];
            s2 = d[2];
            s3 = d[3];
            s4 = d[4];
            s5 = d[5];
            if (stage == 0) {
                double i_ = d[6], v_ = d[7], r_ = d[8], tau_ = d[9];
                g1 = s1; /* the slopes at the step's start (speed reversals) */
                g3 = s3;
                double tau = fabs(tau_);
                if (tau > max_tau)
                    max_tau = tau;
                if (fabs(r_) >= ilim || fabs(v_) >= vlim)
                    sat = 1.0;
                if (fabs(i_) > max_cur) {
                    max_cur = fabs(i_);
                    snapshot(snap, S_PEAK, p, pd, q, qd, i_, xi, s, x, nx, t, iref);
                }
                double defl = fabs(p - q);
                if (defl > max_defl) {
                    max_defl = defl;
                    snapshot(snap, S_DEFLECTION, p, pd, q, qd, cur, xi, s, x, nx, t, iref);
                }
                if (to_record == 0 || step == n_steps) {
                    to_record = rec_every;
                    double *row = out_x + n_rec * nx, *arow = out_aux + n_rec * NAUX;
                    out_t[n_rec] = t;
                    put_state(row, p, pd, q, qd, cur, xi, s);
                    for (long j = NX_PHYS; j < nx; j++)
                        row[j] = x[j];
                    arow[AUX_I] = i_;
                    arow[AUX_V] = v_;
                    arow[AUX_IREF] = r_;
                    arow[AUX_TAU] = tau_;
                    n_rec += 1;
                }
                to_record -= 1;
                status = step_status(p, pd, q, qd, cur, xi, s, x, nx, tau, P, err_mode, rigid);
                if (status != OK || step == n_steps) {
                    done = 1;
                    break;
                }
                if (smooth) {
                    m = smooth_substeps(P, T, n_max, p, pd, s1, dt);
                    if (m > 1)
                        break;
                }
            }
            u0 += w * s0;
            u1 += w * s1;
            u2 += w * s2;
            u3 += w * s3;
            u4 += w * s4;
            u5 += w * s5;
        }
        if (done)
            break;
        if (m > 1) {
            PhysState r = refined_step(m, t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, x, nx, xs, k1, k2, k3, k4,
                                       cmd);
            set_state(r, &p, &pd, &q, &qd, &cur, &xi);
            continue;
        }
        if (stick) {
            /* a node carrying friction may reverse or break away within the step (the motor side or
               the load: ends; the full chain's intermediate nodes: mask): split it there */
            int ends = turned || switch_ahead(pd, pd + sixth * u1, pd + dt * g1, qd, qd + sixth * u3, qd + dt * g3,
                                              P, rigid);
            int64_t mask = lands ? node_flags(x, k1, k2, k3, k4, sixth, P) : 0;
            if (ends || mask) {
                PhysState r = switched_step(t, dt, p, pd, q, qd, cur, xi, s, P, n_par, T, iref, cont, rigid, x, nx,
                                            xs, k1, k2, k3, k4, pd + sixth * u1, qd + sixth * u3, x0, PW, pw_stride,
                                            ends, mask);
                set_state(r, &p, &pd, &q, &qd, &cur, &xi);
                continue;
            }
        }
        if (cont)
            for (long j = NX_PHYS; j < nx; j++)
                x[j] += sixth * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
        p = p + sixth * u0;
        pd = pd + sixth * u1;
        q = q + sixth * u2;
        qd = qd + sixth * u3;
        cur = cur + sixth * u4;
        xi = xi + sixth * u5;
    }
    put_state(x, p, pd, q, qd, cur, xi, s);
    snapshot(snap, S_END, p, pd, q, qd, cur, xi, s, x, nx, t, iref);
    carry[C_IREF] = iref;
    carry[C_TO_SAMPLE] = (double)to_sample;
    carry[C_TO_RECORD] = (double)to_record;
    carry[C_NREC] = (double)n_rec;
    carry[C_MAX_TAU] = max_tau;
    carry[C_MAX_ERR] = max_err;
    carry[C_MAX_CUR] = max_cur;
    carry[C_MAX_DEFL] = max_defl;
    carry[C_SAT] = sat;
    long done_steps = last < n_steps ? last : n_steps;
    fig[F_STATUS] = (double)status;
    fig[F_STEP] = (double)(status != OK ? step : done_steps);
    fig[F_ERR] = max_err;
    fig[F_CUR] = max_cur;
    fig[F_SAT] = sat;
    fig[F_TAU] = max_tau;
    LoopResult res = {status, status != OK ? step : done_steps, n_rec, max_tau, iref};
    return res;
}

/* The cam paper's scheme (and the array form of RK4 when paper_scheme is 0), steps first ..
   last - 1 of n_steps with carry as rk4 takes them (servo_toolkit.sim.integrators._paper).
   scratch: 5 nx + max(nx, 1) doubles (the stages' slopes and state, the controller's work). */
static inline LoopResult paper(double *x, long nx, const double *P, Tab T, double t0, double dt, long first,
                               long last, long n_steps, long sub, double iref, int paper_scheme, long rec_every,
                               double *out_t, double *out_x, double *out_aux, double *carry, double *scratch)
{
    double *k1 = scratch, *k2 = scratch + nx, *k3 = scratch + 2 * nx, *k4 = scratch + 3 * nx;
    double *xs = scratch + 4 * nx, *work = scratch + 5 * nx;
    double aux[NAUX], aux2[NAUX];
    long n_rec = 0;
    double max_tau = 0.0;
    int err_mode = P[STROKE_MODE] == 0.0;
    long qi = P[RIGID] > 0.0 ? 0 : 2;
    double c = P[HALF_PLAY];
    /* RK4's array form takes the register loop's substeps through the smooth signs' band */
    int smooth = !paper_scheme && has_smooth_signs(P);
    double n_max = smooth ? ratio_bound(P, T) : 0.0;
    long to_sample = 0;
    long to_record = 0;
    if (first > 0) {
        iref = carry[C_IREF];
        to_sample = (long)carry[C_TO_SAMPLE];
        to_record = (long)carry[C_TO_RECORD];
        n_rec = (long)carry[C_NREC];
        max_tau = carry[C_MAX_TAU];
    }
    long stop = last >= n_steps ? n_steps + 1 : last;
    for (long step = first; step < stop; step++) {
        double t = t0 + step * dt;
        if (sub > 0) {
            if (to_sample == 0) {
                iref = controller_sample(t, x, P, T, work);
                to_sample = sub;
            }
            to_sample -= 1;
        }
        rhs(t, x, nx, P, T, iref, k1, aux);
        double tau = fabs(aux[AUX_TAU]);
        if (tau > max_tau)
            max_tau = tau;
        if (to_record == 0 || step == n_steps) {
            to_record = rec_every;
            out_t[n_rec] = t;
            for (long j = 0; j < nx; j++)
                out_x[n_rec * nx + j] = x[j];
            for (long j = 0; j < NAUX; j++)
                out_aux[n_rec * NAUX + j] = aux[j];
            n_rec += 1;
        }
        to_record -= 1;
        if (!_finite(x, nx) || !isfinite(tau)) {
            LoopResult res = {NONFINITE, step, n_rec, max_tau, iref};
            return res;
        }
        if (err_mode && (x[qi] > P[STROKE_HI] || x[qi] < P[STROKE_LO])) {
            LoopResult res = {STROKE_END, step, n_rec, max_tau, iref};
            return res;
        }
        if (step == n_steps)
            break;
        /* through the smooth signs' band m RK4 substeps, as rk4 takes them; else (m = 1) the step */
        long m = smooth ? smooth_substeps(P, T, n_max, x[0], x[1], k1[1], dt) : 1;
        double h = m == 1 ? dt : dt / (double)m;
        for (long k = 0; k < m; k++) {
            double tk = t + (double)k * h;
            if (k > 0)
                rhs(tk, x, nx, P, T, iref, k1, aux2);
            for (long stage = 0; stage < 3; stage++) { /* stages 2-4 in one loop (see rk4) */
                double hs = stage == 2 ? h : 0.5 * h;
                double *kin = stage == 0 ? k1 : (stage == 1 ? k2 : k3);
                double *kout = stage == 0 ? k2 : (stage == 1 ? k3 : k4);
                if (paper_scheme) { /* frozen configuration: no position slope enters the later stages */
                    kin[0] = 0.0;
                    kin[2] = 0.0;
                    kin[6] = 0.0;
                }
                for (long j = 0; j < nx; j++)
                    xs[j] = x[j] + hs * kin[j];
                rhs(tk + hs, xs, nx, P, T, iref, kout, aux2);
            }
            double p_old = x[0];
            double q_old = x[2];
            double p_speed = x[1];
            for (long j = 0; j < nx; j++)
                x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            if (P[STICK] > 0.0 && x[1] * p_speed < 0.0 && (P[TS_M] > 0.0 || P[TS_L] > 0.0)) {
                /* friction that holds, in the fixed-configuration scheme: a speed reversal ends the
                   step at rest (Karnopp), where the friction decides between stick and slip */
                x[1] = 0.0;
                if (qi == 0)
                    x[3] = 0.0;
            }
            if (paper_scheme) { /* positions by summation from the new velocities (the RK4 sum above moved them) */
                x[0] = p_old + h * x[1];
                x[2] = q_old + h * x[3];
                double p = x[0];
                if (p > p_old && p > x[6] + c)
                    x[6] = p - c;
                else if (p < p_old && p < x[6] - c)
                    x[6] = p + c;
            }
        }
    }
    carry[C_IREF] = iref;
    carry[C_TO_SAMPLE] = (double)to_sample;
    carry[C_TO_RECORD] = (double)to_record;
    carry[C_NREC] = (double)n_rec;
    carry[C_MAX_TAU] = max_tau;
    LoopResult res = {OK, last < n_steps ? last : n_steps, n_rec, max_tau, iref};
    return res;
}

#endif
