/* The right-hand side of the closed loop: rhs_phys (the physical states) and rhs (with the
   continuous controller), exported to Python by servo_toolkit.sim.kernel, whose docstring keeps
   the same equations.

   One physics, used by every integrator (fixed-step RK4, the cam paper's scheme, the stiff
   reference solver, python-control and the Jacobian estimate). Layout of x and P in layout.h
   (servo_toolkit/sim/layout.py).

   Equations (generalized coordinates p, q at the output; N(p) motor rad per output rad):

       J_d(p) p'' + J_d'(p) p'^2 / 2 = N(p) tau_m - f - K'(p) z^2 / 2
       J_L q''                       = f + M_hinge(q, q') + M_stop(q, q')
       (rigid chain ending in a cam, q the cam angle: J(q) q'' + J'(q) q'^2 / 2
        = N tau_m + M_hinge - M_g, M_g = (sigma f - G_x) ds/dq the follower's weight and guide
        friction, seed 002 eqs 1 and 3, sigma = sign(ds/dq) tanh(omega_m / w_s))
       tau_m = Kt i - b omega_m - Tc tanh(omega_m / w_s),   omega_m = N(p) p'
       (with the drivetrain's loss, lossy: N tau_m and the inertia before the losses, J_w,
        scale by 1 - c; the rest of J_d is as it is)
       L i' = v - R i - Ke omega_m                          (or i = (v - Ke omega_m) / R, L = 0)

   with the elasto-backlash contact law of Modelica's ElastoBacklash (contact): deflection
   d = p - q, play +-c, penetration z = d -+ c beyond the play, spring part tau_c = K z,
   damper part tau_d = beta K d', and on the positive side f = tau_c + min(tau_c, tau_d) if
   tau_c + tau_d > 0 else 0 (mirrored on the negative side; f = 0 inside the play; with no
   play, f = tau_c + tau_d). The damper part is bounded by the spring part,
   |f - tau_c| <= |tau_c|, so f is continuous at engagement (f -> 0 as z -> 0 at any d') and
   never pulls. The potential K(p) z^2 / 2 gives the K'(p) term, so the undamped drivetrain
   conserves energy exactly and the damped one never gains energy. A rigid chain uses
   J(p) = J_d + J_L and q = p.

   Current loop: PI with voltage clamp and back-calculation anti-windup,
   xi' = Kii e + (v - v_c) Kii / Kpi (tracking time constant = the integral time Kpi / Kii):
   continuous in the state, so adaptive solvers integrate through saturation.

   Friction that holds (STICK) is compiled in; every integrator, the batch included, runs this
   one right-hand side. */
#ifndef SERVO_RHS_H
#define SERVO_RHS_H

#include "common.h"
#include "vmath.h"
#include "tables.h"
#include "friction.h"
#include "compliance.h"
#include "control.h"
#include "cam.h"

/* The right-hand side's results into out[10]: the physical states' rates p', pd', q', qd', i',
   xi', then the current, the voltage, the held or computed i_ref and the motor torque. */
static inline void put_rates(double *out, double dp, double dpd, double dq, double dqd, double di, double dxi,
                             double cur, double v, double iref, double tau)
{
    out[0] = dp;
    out[1] = dpd;
    out[2] = dq;
    out[3] = dqd;
    out[4] = di;
    out[5] = dxi;
    out[6] = cur;
    out[7] = v;
    out[8] = iref;
    out[9] = tau;
}

/* dx/dt of the physical states (x[0:7] passed as scalars), returned in out:
   p', pd', q', qd', i', xi', i, v, i_ref, tau_m; s' = 0. Only the continuous motion controller
   and the full chain's intermediate nodes touch the arrays: they read their states in
   x[NX_PHYS:] and write their derivatives into dx[NX_PHYS:] (nothing else is written; a
   continuous controller with back-calculation gains, AW, adds Kaw g (clamped - unclamped) to
   its derivative while its output is clamped, a law continuous in the state, like the
   current PI's).

   cmd: NULL, or the continuous controller's command kept by the caller, [t, r, i_ff, w_ff]:
   at the time cmd[0] the command is taken from it, at any other time it is evaluated and
   kept there (RK4's second and third stages share their time, so the command is
   evaluated once for both; the numbers are the same either way). */
ST_ALWAYS_INLINE ST_FLATTEN void rhs_phys_inline(double t, double p, double pd, double q, double qd, double cur, double xi,
                                      double s, const double *P, Tab T, double iref_held, double *x, double *dx,
                                      double out[10], double *cmd)
{
    long kc;
    double tc;
    cell(P, p, &kc, &tc);
    double hc = P[TAB_H];
    double ih = P[INV_H];
    double jd, djd, n, dn;
    interp(T, T_J, kc, tc, hc, ih, &jd, &djd);
    interp(T, T_N, kc, tc, hc, ih, &n, &dn);
    double wm = n * pd;
    long mode = IX(P[CMODE]);
    double iref, v, di, dxi;
    /* --- controller and electrics */
    if (mode == OPEN_LOOP) {
        iref = 0.0;
        /* a constant voltage, plus a sine (its kernel command about REF_OFF, never shaped)
           for a dwell */
        v = clip(P[V_OPEN] + (command(t, P) - P[REF_OFF]), P[VLIM]);
        if (P[L] > 0.0) {
            di = (v - P[R] * cur - P[KE] * wm) * P[INV_L];
        } else {
            cur = (v - P[KE] * wm) / P[R];
            di = 0.0;
        }
        dxi = 0.0;
    } else {
        if (mode == CONTINUOUS) {
            double r, i_ff, w_ff;
            if (cmd != NULL && cmd[0] == t) {
                r = cmd[1];
                i_ff = cmd[2];
                w_ff = cmd[3];
            } else {
                continuous_command(t, P, T, &r, &i_ff, &w_ff);
                if (cmd != NULL) {
                    cmd[0] = t;
                    cmd[1] = r;
                    cmd[2] = i_ff;
                    cmd[3] = w_ff;
                }
            }
            double y = motion(x, P, r, q, wm - w_ff, dx, NX_PHYS, 1) + i_ff;
            iref = clip(y, P[ILIM]);
            long o = IX(P[AW]);
            if (o > 0 && iref != y) {
                /* continuous back-calculation: the integral bleeds the clamp's excess at Kaw */
                long nc = IX(P[NC]);
                double bleed = P[o + nc] * (iref - y);
                for (long j = 0; j < nc; j++)
                    dx[NX_PHYS + j] += P[o + j] * bleed;
            }
        } else {
            iref = iref_held;
        }
        if (P[L] > 0.0) {
            double e = iref - cur;
            double vc = P[KPI] * e + xi;
            v = clip(vc, P[VLIM]);
            di = (v - P[R] * cur - P[KE] * wm) * P[INV_L];
            /* back-calculation anti-windup: continuous, bleeds the clamp excess off the integral */
            dxi = P[KII] * e + (v - vc) * P[KAW];
        } else {
            v = clip(P[R] * iref + P[KE] * wm, P[VLIM]);
            cur = (v - P[KE] * wm) / P[R];
            di = 0.0;
            dxi = 0.0;
        }
    }
    double tau = P[KT] * cur;
    /* friction: exact stick (STICK) or the smooth Coulomb model */
    int stick = P[STICK] > 0.0;
    double tw = vtanh(wm * P[WS]); /* the motor speed's smooth sign: the smooth Coulomb friction's and the loss's */
    double fm;
    if (stick)
        fm = pd == 0.0 ? 0.0 : slip_friction(wm, P[TC], P[TS_M], P[INV_VS_M], P[DIR_M]);
    else
        fm = P[TC] * tw;
    double sw = speed_sign(n, tw);
    double tau_shaft = tau - P[BM] * wm - fm;
    double nts = n * tau_shaft;
    /* --- load side: hinge moment, stroke-end stop, the load's friction while it slides */
    double ql, qld;
    if (P[RIGID] > 0.0) {
        ql = p;
        qld = pd;
    } else {
        ql = q;
        qld = qd;
    }
    double m_load = -P[HINGE_M] - P[HINGE_K] * ql - P[HINGE_D] * qld;
    if (P[STROKE_MODE] == STROKE_STOP) {
        if (ql > P[STROKE_HI])
            m_load += dmin(-P[KSTOP] * (ql - P[STROKE_HI]) - P[DSTOP] * qld, 0.0);
        else if (ql < P[STROKE_LO])
            m_load += dmax(-P[KSTOP] * (ql - P[STROKE_LO]) - P[DSTOP] * qld, 0.0);
    }
    if (stick && qld != 0.0 && P[TS_L] > 0.0)
        m_load -= slip_friction(qld, P[TC_L], P[TS_L], P[INV_VS_L], P[DIR_L]);
    if (P[RIGID] > 0.0) {
        double pdd;
        lossy(P, &nts, &jd, &djd, n, dn, m_load, sw);
        if (P[CAM] > 0.0) {
            /* chain ends in a cam: the follower's weight and guide friction load the shaft,
               M_g = (sigma f - G_x) ds/dq (seed 002 eq 3; its m a part is in J and J') */
            long oc = IX(P[CAM]);
            double m_g;
            shaft_acceleration(P + oc, p, pd, nts + m_load, jd, 0.5 * djd * pd * pd, n * P[WS], &pdd, &m_g);
            if (stick && pd == 0.0) /* motor and load at rest on one node: held by the gear's band, or breaking away */
                pdd = gear_at_rest(nts, pdd * jd - nts, n * P[TS_M], P[TS_L], P[HOLD_FWD], P[HOLD_BACK],
                                   P[HOLD_GAUGE]) / jd;
        } else {
            double m_p = nts - 0.5 * djd * pd * pd + m_load;
            if (stick && pd == 0.0) /* motor and load at rest on one node: held by the gear's band, or breaking away */
                m_p = gear_at_rest(nts, m_load, n * P[TS_M], P[TS_L], P[HOLD_FWD], P[HOLD_BACK], P[HOLD_GAUGE]);
            pdd = m_p / jd;
        }
        put_rates(out, pd, pdd, pd, pdd, di, dxi, cur, v, iref, tau);
        return;
    }
    if (P[NMID] > 0.0) {
        double pdd, qdd;
        chain_accelerations(p, pd, q, qd, nts, jd, djd, n, dn, m_load, kc, tc, P, T, x, dx, sw, &pdd, &qdd);
        if (stick)
            stick_nodes(&pdd, &qdd, pd, qd, jd, n, P);
        put_rates(out, pd, pdd, qd, qdd, di, dxi, cur, v, iref, tau);
        return;
    }
    /* --- compliance with backlash */
    double k, dk;
    interp(T, T_K, kc, tc, hc, ih, &k, &dk);
    k *= P[KSCALE];
    dk *= P[KSCALE];
    double c = P[HALF_PLAY];
    double dd = pd - qd;
    double z, f;
    if (P[PAPER] > 0.0) {
        /* the cam paper's play operator: the spring acts on s - q, s held inside the play */
        z = s - q;
        f = k * z;
        if (fabs(p - s) >= c * (1.0 - 1e-9)) /* in contact (s was pushed to p -+ c) */
            f += P[BETA] * k * dd;
    } else if (c <= B_EPS) {
        /* no play (Modelica: b <= 1e-10 rad): a plain spring-damper, which may pull */
        z = p - q;
        f = k * z + P[BETA] * k * dd;
    } else {
        double d = p - q;
        if (d > c)
            z = d - c;
        else if (d < -c)
            z = d + c;
        else
            z = 0.0;
        f = contact(k * z, P[BETA] * k * dd);
    }
    lossy(P, &nts, &jd, &djd, n, dn, -f - 0.5 * dk * z * z, sw);
    double m_p = nts - 0.5 * djd * pd * pd - f - 0.5 * dk * z * z; /* the moments on the motor side and the load */
    double m_q = f + m_load;
    if (stick)
        stick_moments(&m_p, &m_q, pd, qd, n, nts, -f - 0.5 * dk * z * z, P);
    put_rates(out, pd, m_p / jd, qd, m_q * P[INV_JL], di, dxi, cur, v, iref, tau);
}


/* rhs_phys_inline as a function of its own (out of line): the callers that are not the
   fixed-step loop's hot path (the array form rhs, the paper's scheme, the switch location)
   call it instead of inlining their own copy. */
ST_NOINLINE void rhs_phys(double t, double p, double pd, double q, double qd, double cur, double xi, double s,
                          const double *P, Tab T, double iref_held, double *x, double *dx, double out[10])
{
    rhs_phys_inline(t, p, pd, q, qd, cur, xi, s, P, T, iref_held, x, dx, out, NULL);
}

/* dx/dt of the closed loop (x of nx states); aux receives current, voltage, i_ref and motor
   torque. The sampled controller's and the speed estimator's states are held (derivative 0). */
static inline void rhs(double t, double *x, long nx, const double *P, Tab T, double iref_held, double *dx,
                       double *aux)
{
    double out[10];
    for (long j = NX_PHYS; j < nx; j++) /* sampled controller and estimator states are held */
        dx[j] = 0.0;
    rhs_phys(t, x[0], x[1], x[2], x[3], x[4], x[5], x[6], P, T, iref_held, x, dx, out);
    dx[0] = out[0];
    dx[1] = out[1];
    dx[2] = out[2];
    dx[3] = out[3];
    dx[4] = out[4];
    dx[5] = out[5];
    dx[6] = 0.0;
    aux[AUX_I] = out[6];
    aux[AUX_V] = out[7];
    aux[AUX_IREF] = out[8];
    aux[AUX_TAU] = out[9];
}

#endif
