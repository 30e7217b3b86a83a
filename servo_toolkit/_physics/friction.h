/* Friction that holds, inside the kernels (Karnopp-type stick at zero speed; slip_friction,
   stuck_or_breaking and gear_at_rest are exported to Python by servo_toolkit.sim.kernel).

   A node carrying friction (the motor shaft, the load) slides with the Stribeck law

       F(v) = (Tc + (Ts - Tc) exp(-(v / v_st)^2)) sign(v)           (v != 0)

   and, at exactly zero speed, sticks: its acceleration is 0 while the applied moment (every
   other moment on the node) stays within the breakaway level Ts; beyond it the node breaks
   away against Ts (the Stribeck curve's value at v = 0+). A node stuck at v = 0 keeps its
   position exactly (RK4's stages all see v = 0 and zero acceleration). The integrators locate
   a node's speed reversal within the step and restart it at v = 0 exactly, so the stick test
   is met where the physics meets it; the reference solver stops on the same reversal as an
   event. */
#ifndef SERVO_FRICTION_H
#define SERVO_FRICTION_H

#include "common.h"
#include "vmath.h"

/* Sliding friction at speed v != 0, signed with v (or with direction when it is not 0: the
   friction of a motion continued past its speed's zero, which the switch location
   integrates): Tc + (Ts - Tc) exp(-(v / v_st)^2).

   The exponential is exp_neg's (no library call; within 1 ulp), taken as 0 beyond
   (v / v_st)^2 = 44 (exp(-44) = 8e-20). */
static inline double slip_friction(double v, double tc, double ts, double inv_vs, double direction)
{
    double y = v * inv_vs;
    double y2 = y * y;
    double stribeck = y2 >= 2.0 * TANH_ONE ? 0.0 : exp_neg(y2);
    double mag = tc + (ts - tc) * stribeck;
    int ahead = direction == 0.0 ? v > 0.0 : direction > 0.0;
    return ahead ? mag : -mag;
}

/* The net moment on a node at rest: 0 while |applied| <= cap (it sticks), else the applied
   moment less the breakaway level cap against it. */
static inline double stuck_or_breaking(double applied, double cap)
{
    if (applied > cap)
        return applied - cap;
    if (applied < -cap)
        return applied + cap;
    return 0.0;
}

/* The net moment on a node at rest behind a lossy gear (LossyGear's stuck mode): 0 while it
   holds, else the applied moment less the breakaway levels against it.

   torque is the motor side's torque at the gear's output (N tau at rest), moment the moment
   on the far side (the load's, or a compliance's on the motor side), cap_t and cap_m their
   breakaway levels (N Ts_m; Ts_L or 0), fwd_loss = 1/eta - 1 and back_loss = 1 - max(eta_b, 0)
   (both 0: a lossless gear). The gear passes eta T on while the motor side drives and
   T / eta_b while the far side drives it back; for motion forward, with T = torque - cap_t and
   M = moment - cap_m, the node breaks away where

       h(T) + M > 0,   h(T) = eta T (T > 0), T / eta_b (T < 0, -inf for eta_b <= 0),

   computed at the motor side as the distance T + g(M) > 0, g(M) = eta_b M (M > 0: the far
   side drives through the gear), M / eta (M < 0): the same sign, finite for a self-locking
   gear, and continuous. Backward mirrored (T = torque + cap_t, M = moment + cap_m). Both
   cannot hold at once, and where one does the lossless net moment applied -+ (cap_t + cap_m)
   has its sign (h(T) <= T forward), so the moment returned is the sliding law's at 0+, where
   the loss's smooth speed sign is 0.

   gauge (HOLD_GAUGE): 0, the net moment; 1, the signed breakaway distance
   max(forward, backward) (> 0 beyond the band: the zero the breakaway's location finds);
   2, forward less backward (> 0: it would break away forward). */
static inline double gear_at_rest(double torque, double moment, double cap_t, double cap_m, double fwd_loss,
                                  double back_loss, double gauge)
{
    double tf = torque - cap_t;
    double mf = moment - cap_m;
    double fwd = tf + (mf > 0.0 ? mf - back_loss * mf : mf + fwd_loss * mf);
    double tb = torque + cap_t;
    double mb = moment + cap_m;
    double bwd = -tb - (mb < 0.0 ? mb - back_loss * mb : mb + fwd_loss * mb);
    double applied = torque + moment;
    double cap = cap_t + cap_m;
    double net = fwd > 0.0 ? applied - cap : (bwd > 0.0 ? applied + cap : 0.0);
    if (gauge > 0.0)
        return gauge < 1.5 ? dmax(fwd, bwd) : fwd - bwd;
    return net;
}

/* The net moment on the full chain's intermediate node j (1..NMID) moving at v, from the
   applied moment (every other moment on it: the segments on either side, the velocity
   terms), with the node's own friction (NODE_FRIC; none when 0): its viscous part, and with
   friction that holds (STICK) its sliding law (slip_friction) or, at exactly v = 0, the
   stick law (stuck_or_breaking) against its breakaway level. The chain's mass matrix is
   diagonal in the node coordinates, so the decision is the node's alone. */
static inline double node_moment(const double *P, long j, double v, double applied)
{
    long o = IX(P[NODE_FRIC]);
    if (o == 0)
        return applied;
    long b = o + NF_STRIDE * (j - 1);
    applied -= P[b + NF_VISC] * v;
    double ts = P[b + NF_TS];
    if (ts > 0.0 && P[STICK] > 0.0) {
        if (v == 0.0)
            return stuck_or_breaking(applied, ts);
        return applied - slip_friction(v, P[b + NF_TC], ts, P[b + NF_INV_VS], P[b + NF_DIR]);
    }
    return applied;
}

/* The motor side and the load of the full chain at rest: each sticks while the moment on it
   (its acceleration without friction times its inertia) stays within its breakaway level,
   else breaks away against it (the chain's loss, spread over its segments, is left out at
   rest here: gear_at_rest of a lossless gear). *pdd and *qdd in and out. */
static inline void stick_nodes(double *pdd, double *qdd, double pd, double qd, double jd, double n,
                               const double *P)
{
    if (pd == 0.0)
        *pdd = gear_at_rest(*pdd * jd, 0.0, n * P[TS_M], 0.0, 0.0, 0.0, P[HOLD_GAUGE]) / jd;
    if (qd == 0.0 && P[TS_L] > 0.0)
        *qdd = gear_at_rest(*qdd / P[INV_JL], 0.0, P[TS_L], 0.0, 0.0, 0.0, P[HOLD_GAUGE]) * P[INV_JL];
}

/* The two-mass chain's motor side and load at rest, on their moments (accelerations times
   inertias). The motor side (motor torque at the gear's output nts, the compliance's moment
   on it spring) is held while the torques on the gear stay within its band (gear_at_rest),
   the load while the moment on it stays within its breakaway level; else each breaks away
   against its level. *m_p and *m_q in and out. */
static inline void stick_moments(double *m_p, double *m_q, double pd, double qd, double n, double nts,
                                 double spring, const double *P)
{
    if (pd == 0.0)
        *m_p = gear_at_rest(nts, spring, n * P[TS_M], 0.0, P[HOLD_FWD], P[HOLD_BACK], P[HOLD_GAUGE]);
    if (qd == 0.0 && P[TS_L] > 0.0)
        *m_q = gear_at_rest(*m_q, 0.0, P[TS_L], 0.0, 0.0, 0.0, P[HOLD_GAUGE]);
}

#endif
