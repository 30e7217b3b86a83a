/* The drivetrain's compliances and losses inside the kernels: the elasto-backlash contact law
   (exported as servo_toolkit.sim.kernel.contact), a compliance's force, the loss coefficient
   and its folding into the motor side's equation, and the full chain's node accelerations (the
   equations in rhs.h and servo_toolkit/sim/chain_model.py). */
#ifndef SERVO_COMPLIANCE_H
#define SERVO_COMPLIANCE_H

#include "common.h"
#include "vmath.h"
#include "tables.h"
#include "friction.h"

/* half plays at or below this (rad) act as a plain spring-damper (Modelica's bEps = 1e-10 rad
   total backlash) */
#define B_EPS 0.5e-10

/* Modelica ElastoBacklash contact moment from the spring part tau_c = K z (sign = contact
   side, 0 inside the play) and the damper part tau_d = beta K d'.

   Positive side: 0 if tau_c + tau_d <= 0 (no pulling), else tau_c + min(tau_c, tau_d);
   negative side mirrored. Continuous in z (|f| <= 2 |tau_c|), no events. */
static inline double contact(double tau_c, double tau_d)
{
    if (tau_c > 0.0) {
        if (tau_c + tau_d <= 0.0)
            return 0.0;
        return tau_c + dmin(tau_c, tau_d);
    }
    if (tau_c < 0.0) {
        if (tau_c + tau_d >= 0.0)
            return 0.0;
        return tau_c + dmax(tau_c, tau_d);
    }
    return 0.0;
}

/* The loss coefficient at the smooth sign sg in [-1, 1] of the power flow:
   ETA_MEAN sg + ETA_HALF a(sg), 1 - eta at sg = 1 (driving), 1 - 1/eta_b at sg = -1
   (back-driven), smooth and monotone in sg, so that inside the smoothing band the loss stays
   between either mode's (1 - c >= eta > 0).

   a(sg) is an even, smooth |sg| with a(+-1) = 1: sg^2 (the quadratic blend) wherever that is
   monotone, r = ETA_MEAN / |ETA_HALF| >= 2 (1/eta_b - 1 <= 3 (1 - eta): every chain but a
   near-self-locking one); otherwise the rounded |sg| whose steepest slope is r,
   a = sg^2 (sqrt(1 + w^2) + 1) / (sqrt(1 + w^2 sg^2) + 1), w = sqrt(r (2 - r)) / (r - 1)
   (sqrt(sg^2 + e^2) - e scaled to 1 at +-1, e = 1/w; w = 0 is the quadratic). The quadratic
   there would overshoot 1 - eta, past 1 (a negative efficiency) near self-locking: 1.42 at
   eta = 0.29, eta_b = 0.1, where the motor side's inertia J_d - c J_w passes near zero. */
static inline double blend(const double *P, double sg)
{
    double mean = P[ETA_MEAN], half = P[ETA_HALF];
    double a = sg * sg;
    if (mean < 2.0 * fabs(half)) {
        double r = mean / fabs(half);
        double w2 = r * (2.0 - r) / dmax((r - 1.0) * (r - 1.0), 1e-300);
        a *= (sqrt(1.0 + w2) + 1.0) / (sqrt(1.0 + w2 * a) + 1.0);
    }
    return mean * sg + half * a;
}

/* The drivetrain's loss coefficient c at this state: 1 - eta driving, 1 - 1/eta_b back-driven
   (negative), blended by the smooth signs of the transmitted torque and of the speed
   (c T p' >= 0: the loss never supplies power); 0 for a lossless chain. sw is the speed's
   smooth sign tanh(|N| p' / w_s) (speed_sign: the Coulomb friction's tanh(omega_m / w_s)
   times the sign of N, one evaluation for both).

   The sign of the transmitted torque T is that of the lossless torque passed on past the
   members before the losses (rotor, pinion: inertia J_w = JW n^2 at the output),
   T = nts - J_w p'' with jd p'' = nts + rest, computed without its velocity terms (of the
   order of the ratio's variation) and times jd / J_d(q0) (the same sign; the scale of the
   smooth sign varies with J_d(p) / J_d(q0), a few per cent along a stroke). */
static inline double loss_coefficient(const double *P, double nts, double jd, double n, double rest, double sw)
{
    if (P[ETA_MEAN] <= 0.0)
        return 0.0;
    double jw = P[JW] * n * n;
    double t_free = ((jd - jw) * nts - jw * rest) * P[INV_JD0];
    return blend(P, vtanh(t_free * P[INV_TAU_S]) * sw);
}

/* The output speed's smooth sign tanh(|N| p' / w_s) from the motor speed's
   tw = tanh(N p' / w_s) (tanh is odd: the same value). */
static inline double speed_sign(double n, double tw)
{
    return n >= 0.0 ? tw : -tw;
}

/* The drivetrain's loss (LossyGear-like) folded into the motor side's equation
   jd p'' = nts - djd p'^2 / 2 + rest: *nts, *jd, *djd in and out, with the loss.

   The loss acts on the torque transmitted past the members before it (rotor, pinion:
   inertia J_w = JW n^2 at the output), T = nts - J_w p'' - J_w' p'^2 / 2, which loses c T
   (loss_coefficient). Solved for p'': nts and J_w scale by (1 - c), the rest of the motor
   side stays. */
static inline void lossy(const double *P, double *nts, double *jd, double *djd, double n, double dn, double rest,
                         double sw)
{
    if (P[ETA_MEAN] <= 0.0)
        return;
    double c = loss_coefficient(P, *nts, *jd, n, rest, sw);
    *nts = *nts - c * *nts;
    *jd = *jd - c * P[JW] * n * n;
    *djd = *djd - c * 2.0 * P[JW] * n * dn;
}

/* Force *f of a compliance of stiffness k with half play c and structural damping beta k at
   deflection d and rate dd (contact beyond the play; a plain spring-damper without one), and
   *z the spring's deflection beyond the play. */
static inline void segment_force(double k, double d, double dd, double c, double beta, double *f, double *z)
{
    if (c <= B_EPS) {
        *f = k * d + beta * k * dd;
        *z = d;
        return;
    }
    double zz;
    if (d > c)
        zz = d - c;
    else if (d < -c)
        zz = d + c;
    else
        zz = 0.0;
    *f = contact(k * zz, beta * k * dd);
    *z = zz;
}

/* Node j's inertia at the motor-side position and its derivative along it, J_j - c J_w,j and
   J_j' - c J_w,j' (j = 1..NMID + 1: the intermediate nodes, then the load; c the loss
   coefficient, 0 for a lossless chain). */
static inline void node_inertia(const double *P, Tab T, long j, double c, long kc, double tc, double hc, double ih,
                                double *jj, double *dj)
{
    long r = IX(P[ROW_NODE]) + NODE_ROWS * (j - 1);
    interp(T, r, kc, tc, hc, ih, jj, dj);
    if (c != 0.0) {
        double jw, djw;
        interp(T, r + 2, kc, tc, hc, ih, &jw, &djw);
        *jj -= c * jw;
        *dj -= c * djw;
    }
}

/* The inertia of every node beyond the motor side and its derivative along p: the load side
   JL of a two-mass model, the sum of the further nodes' tables of the full chain. */
static inline void inertia_beyond_motor(const double *P, Tab T, long kc, double tc, double hc, double ih,
                                        double *total, double *slope)
{
    long nm = IX(P[NMID]);
    if (nm == 0) {
        *total = P[JL];
        *slope = 0.0;
        return;
    }
    double sum = 0.0, dsum = 0.0;
    for (long j = 1; j < nm + 2; j++) {
        double jj, dj;
        node_inertia(P, T, j, 0.0, kc, tc, hc, ih, &jj, &dj);
        sum += jj;
        dsum += dj;
    }
    *total = sum;
    *slope = dsum;
}

/* The full chain (P[NMID] intermediate nodes, servo_toolkit/sim/chain_model.py): writes the
   intermediate nodes' derivatives into dx and returns (p'', q'') in *pdd, *qdd.

   Node 0 is the motor side p, nodes 1..NMID the intermediate ones y_j, node NMID + 1 the
   load q. Every node's inertia J_j(p) is tabulated along the motor-side position (jd, djd
   for node 0), and segment s (between nodes s and s + 1) has its stiffness k_s(p), play and
   damper beta_s k_s(p) (segment_force, force f_s, deflection beyond the play z_s). Lagrange's
   equations of T = sum_j J_j(p) y_j'^2 / 2 and V = sum_s k_s(p) z_s^2 / 2:

       J_0 p'' = N tau - J_0' p'^2 / 2 + sum_{j>0} J_j' y_j'^2 / 2 - f_0 - sum_s k_s' z_s^2 / 2
       J_j y_j'' = f_{j-1} - f_j - J_j' p' y_j'

   so the undamped, lossless chain conserves T + V exactly. The losses act where the chain
   has them, with one coefficient c for the whole chain (loss_coefficient, judged at the
   motor side): node j's inertia J_j - c J_w,j (J_w,j its inertia before the losses,
   tabulated like J_j), the motor torque (1 - c) N tau and segment s weighted by 1 - c l_s,
   l_s = (1 - eta / Pi_s) / (1 - eta) (driving: eta / Pi, the chain's driving-mode form). The
   power the losses take is then c times the power transmitted past the members before them.
   An intermediate node carrying a stage's friction (NODE_FRIC) slides against it and sticks
   at rest by its own breakaway level (node_moment). */
static inline void chain_accelerations(double p, double pd, double q, double qd, double nts, double jd, double djd,
                                       double n, double dn, double m_load, long kc, double tc, const double *P,
                                       Tab T, const double *x, double *dx, double sw, double *pdd, double *qdd)
{
    (void)dn;
    long nm = IX(P[NMID]);
    long o = IX(P[OFF_NODE]);
    long g = IX(P[OFF_SEG]);
    double hc = P[TAB_H], ih = P[INV_H], ks = P[KSCALE];
    /* segment 0: the motor side against node 1 */
    double k0, dk0, f0, z0;
    interp(T, T_K, kc, tc, hc, ih, &k0, &dk0);
    k0 *= ks;
    dk0 *= ks;
    segment_force(k0, p - x[o], pd - x[o + 1], P[g + SEG_PLAY], P[g + SEG_BETA], &f0, &z0);
    double c = loss_coefficient(P, nts, jd, n, -f0 - 0.5 * dk0 * z0 * z0, sw);
    double w0 = 1.0 - c * P[g + SEG_LOSS];
    double pot = -0.5 * w0 * dk0 * z0 * z0; /* -sum_s w_s k_s' z_s^2 / 2 on the motor side */
    double kin = 0.0;                       /* sum_{j>0} J_j' y_j'^2 / 2 on the motor side */
    double f_in = w0 * f0;                  /* the force the segment before node j passes on to it */
    for (long j = 1; j < nm + 1; j++) {     /* the intermediate nodes */
        long a = o + 2 * (j - 1);
        double y = x[a], yd = x[a + 1];
        double yn, ynd;
        if (j < nm) {
            yn = x[a + 2];
            ynd = x[a + 3];
        } else {
            yn = q;
            ynd = qd;
        }
        double jj, dj;
        node_inertia(P, T, j, c, kc, tc, hc, ih, &jj, &dj);
        kin += 0.5 * dj * yd * yd;
        double kj, dkj;
        interp(T, T_KS + 2 * (j - 1), kc, tc, hc, ih, &kj, &dkj);
        kj *= ks;
        dkj *= ks;
        long gj = g + SEG_STRIDE * j;
        double fj, zj;
        segment_force(kj, y - yn, yd - ynd, P[gj + SEG_PLAY], P[gj + SEG_BETA], &fj, &zj);
        double wj = 1.0 - c * P[gj + SEG_LOSS];
        pot -= 0.5 * wj * dkj * zj * zj;
        dx[a] = yd;
        dx[a + 1] = node_moment(P, j, yd, f_in - wj * fj - dj * pd * yd) / jj;
        f_in = wj * fj;
    }
    double jl, djl;
    node_inertia(P, T, nm + 1, c, kc, tc, hc, ih, &jl, &djl); /* the load */
    kin += 0.5 * djl * qd * qd;
    *qdd = (f_in + m_load - djl * pd * qd) / jl;
    double jw0 = 0.0, djw0 = 0.0;
    if (c != 0.0)
        interp(T, IX(P[ROW_JW0]), kc, tc, hc, ih, &jw0, &djw0);
    *pdd = ((1.0 - c) * nts - 0.5 * (djd - c * djw0) * pd * pd + kin - w0 * f0 + pot) / (jd - c * jw0);
}

#endif
