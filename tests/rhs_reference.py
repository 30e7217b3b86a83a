"""A plain-Python transcription of the compiled right-hand side ``servo_toolkit.sim.kernel.rhs``.

Written from the equations of the kernel modules (their docstrings and code), with the
``math`` module and plain floats; it calls no kernel (nor a kernel's ``py_func``) and reads
only the layout constants (data) from :mod:`servo_toolkit.sim.layout`. It is the test net for
a port of the kernels to another language: the compiled right-hand side must equal
:func:`rhs` at any state (tests/test_rhs_transcription.py draws them). The position command
is in tests/rhs_reference_command.py, the cam shaft in tests/rhs_reference_cam.py.

Covered, as :func:`servo_toolkit.sim.model.build_model` assembles them:

* stroke tables: the cell of a position (clamped, or wrapped for a periodic table) and the
  cubic Hermite value and derivative of a row;
* controller modes: open loop (a constant voltage plus the command's sine, clamped), the
  sampled controller's held current reference, the continuous motion controller integrated
  with the plant (its state derivatives), with the current PI, its voltage clamp and the
  back-calculation anti-windup, or the algebraic current without inductance;
* the command: hold, sine, step, ramp, sampled table (cubic Hermite, periodic or held), the
  jerk-limited move, through the command shaper's impulses; the feedforward (velocity and
  acceleration gains, the model-based inverse dynamics with the chain's loss, the speed
  loop's reference, the half-sample lead);
* the motor's viscous friction and its smooth Coulomb friction Tc tanh(w / w_s), or friction
  that holds: the Stribeck sliding law (with the held direction DIR_M / DIR_L of a continued
  motion) and the stick law at exactly zero speed, LossyGear's stuck mode behind a lossy
  gear (HOLD_FWD / HOLD_BACK) and its breakaway gauges (HOLD_GAUGE 1 and 2);
* the load: hinge moment, stiffness and damping, the elastic stroke-end stop (never pulls),
  the load's sliding friction;
* the drivetrain's loss (LossyGear-like): the loss coefficient from the smooth signs of the
  transmitted torque and of the speed, blended quadratically or by the rounded |sg| near
  self-locking, folded into the motor side's torque and inertia;
* chains: rigid (J(p), q = p), rigid ending in a cam (the follower's weight and guide
  friction by the fixed point of :mod:`servo_toolkit.components.cam.kernels`), two-mass with
  the elasto-backlash contact law (Modelica ``ElastoBacklash``), a plain spring-damper
  without play, the cam paper's play operator (``PAPER``), and the full chain's intermediate
  nodes (every node's inertia along the stroke, each segment's play, damper and loss weight,
  the nodes' own friction, ``NODE_FRIC``) with the motor side and the load sticking at rest.

Left out (not part of ``rhs``): the sampled controller's update and the speed estimators
(:func:`~servo_toolkit.sim.kernel.controller_sample`, once per sample; ``rhs`` holds their
states, derivative 0) and the gain schedule (applied in that update only).

Elementary functions: ``math.tanh`` and ``math.exp`` stand for the kernels' branch-free
:func:`~servo_toolkit.sim.kernel.tanh` and ``exp_neg`` (``vmath.h``, each within 1 ulp of the
library's);
the cut-offs they document (tanh = +-1 from |a| = 22, the Stribeck exponential 0 beyond
exp(-44)) are kept, as they decide values, not only their last bit.
"""

from __future__ import annotations

import math

from servo_toolkit.sim import layout as lo

from .rhs_reference_cam import shaft_acceleration
from .rhs_reference_command import command, reference, reference_rates

#: half plays at or below this (rad) act as a plain spring-damper (Modelica's bEps = 1e-10 rad total)
B_EPS = 0.5e-10


# --- tables --------------------------------------------------------------------------------

def cell(P, q):
    """Cell index and local coordinate in [0, 1] of q in the stroke tables (clamped at their
    ends; a periodic table wraps)."""
    s = (q - P[lo.TAB_LO]) * P[lo.INV_H]
    last = P[lo.TAB_N] - 1.0
    if P[lo.PERIODIC] > 0.0:
        s = s - last * math.floor(s / last)
    if s <= 0.0:
        return 0, 0.0
    if s >= last:
        return int(last) - 1, 1.0
    k = int(s)
    return k, s - k


def interp(T, row, k, t, h, inv_h):
    """Cubic Hermite value and derivative of table ``row`` (its derivatives in ``row + 1``)."""
    y0, y1 = T[row, k], T[row, k + 1]
    m0, m1 = T[row + 1, k] * h, T[row + 1, k + 1] * h
    t2 = t * t
    t3 = t2 * t
    value = (2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * m0 + (3 * t2 - 2 * t3) * y1 + (t3 - t2) * m1
    slope = ((6 * t2 - 6 * t) * (y0 - y1) + (3 * t2 - 4 * t + 1) * m0 + (3 * t2 - 2 * t) * m1) * inv_h
    return value, slope


def row_at(P, T, row, q):
    """Value and derivative of table ``row`` at q."""
    k, t = cell(P, q)
    return interp(T, row, k, t, P[lo.TAB_H], P[lo.INV_H])


# --- elementary functions -------------------------------------------------------------------

def smooth_sign(a):
    """tanh(a), exactly +-1 from |a| = 22 on."""
    return math.copysign(1.0, a) if abs(a) >= 22.0 else math.tanh(a)


def clip(v, lim):
    return lim if v > lim else (-lim if v < -lim else v)


# --- the feedforward (feedforward.h) ---------------------------------------------------------

def inertia_beyond_motor(P, T, q):
    """The inertia beyond the motor side and its slope: JL (two-mass), or the sum of the full
    chain's further node tables."""
    nm = int(P[lo.NMID])
    if nm == 0:
        return P[lo.JL], 0.0
    total = slope = 0.0
    for j in range(1, nm + 2):
        jj, dj = row_at(P, T, int(P[lo.ROW_NODE]) + lo.NODE_ROWS * (j - 1), q)
        total, slope = total + jj, slope + dj
    return total, slope


def feedforward_current(r, rd, rdd, P, T):
    """Kv r' + Ka r'' plus, with FF_MODEL, the rigid chain's inverse dynamics at r over
    N Kt: J r'' + J' r'^2 / 2 against the load's moment, the loss solved for the motor
    torque, the motor's viscous and smooth Coulomb friction."""
    i = P[lo.FF_KV] * rd + P[lo.FF_KA] * rdd
    if P[lo.FF_MODEL] <= 0.0:
        return i
    j, dj = row_at(P, T, lo.T_J, r)
    n, dn = row_at(P, T, lo.T_N, r)
    jb, djb = inertia_beyond_motor(P, T, r)
    j = (j + jb + P[lo.FF_DJ]) * P[lo.FF_JSCALE]
    dj = (dj + djb) * P[lo.FF_JSCALE]
    m_load = -P[lo.HINGE_M] - P[lo.HINGE_K] * r - P[lo.HINGE_D] * rd
    torque = j * rdd + 0.5 * dj * rd * rd - m_load
    if P[lo.ETA_MEAN] > 0.0:
        jw = P[lo.JW] * n * n * P[lo.FF_JSCALE]
        t_before = jw * rdd + P[lo.JW] * P[lo.FF_JSCALE] * n * dn * rd * rd  # the members before the loss
        passed = torque - t_before
        c = blend(P, smooth_sign(passed * P[lo.INV_TAU_S]) * smooth_sign(abs(n) * rd * P[lo.WS]))
        torque = t_before + passed / (1.0 - c)
    wm = n * rd
    return i + (torque / n + P[lo.BM] * wm + P[lo.TC] * smooth_sign(wm * P[lo.WS])) / P[lo.KT]


def continuous_command(t, P, T):
    """(r, i_ff, w_ff) of the continuous controller: the feedforward's when FF_ON (the speed
    reference N(r) r' with FF_SPEED, the current at t + FF_LEAD), else (r(t), 0, 0)."""
    if P[lo.FF_ON] <= 0.0:
        return reference(t, P), 0.0, 0.0
    r, rd, _ = reference_rates(t, P)
    w_ff = row_at(P, T, lo.T_N, r)[0] * rd if P[lo.FF_SPEED] > 0.0 else 0.0
    ra, rda, rdda = reference_rates(t + P[lo.FF_LEAD], P)
    return r, feedforward_current(ra, rda, rdda, P, T), w_ff


def motion_controller(x, P, u, dx):
    """The continuous motion controller: i_ref = C xc + D u, xc' = A xc + B u into dx, with
    u = (r, theta, omega)."""
    nc = int(P[lo.NC])
    oa, ob, oc, od = (int(P[s]) for s in (lo.OFF_A, lo.OFF_B, lo.OFF_C, lo.OFF_D))
    xc = [x[lo.NX_PHYS + j] for j in range(nc)]
    y = P[od] * u[0] + P[od + 1] * u[1] + P[od + 2] * u[2]
    for j in range(nc):
        y += P[oc + j] * xc[j]
    for j in range(nc):
        rate = P[ob + 3 * j] * u[0] + P[ob + 3 * j + 1] * u[1] + P[ob + 3 * j + 2] * u[2]
        for k in range(nc):
            rate += P[oa + j * nc + k] * xc[k]
        dx[lo.NX_PHYS + j] = rate
    return y


# --- friction (friction.h) -------------------------------------------------------------------

def slip_friction(v, tc, ts, inv_vs, direction):
    """Stribeck sliding friction Tc + (Ts - Tc) exp(-(v / v_st)^2), signed with v, or with
    ``direction`` when it is not 0 (a motion continued past its speed's zero)."""
    y = v * inv_vs
    y2 = y * y
    drop = 0.0 if y2 >= 44.0 else math.exp(-y2)
    magnitude = tc + (ts - tc) * drop
    ahead = v > 0.0 if direction == 0.0 else direction > 0.0
    return magnitude if ahead else -magnitude


def stuck_or_breaking(applied, cap):
    """A node at rest: 0 while |applied| <= cap, else the excess beyond the breakaway level."""
    return applied - cap if applied > cap else (applied + cap if applied < -cap else 0.0)


def gear_at_rest(torque, moment, cap_t, cap_m, fwd_loss, back_loss, gauge):
    """LossyGear's stuck mode: the motor side's torque at the gear (``torque``, breakaway
    cap_t) and the far side's moment (cap_m) break away forward where T + g(M) > 0 (T =
    torque - cap_t, M = moment - cap_m, g(M) = eta_b M for M > 0, M / eta for M < 0),
    backward mirrored; the net moment is then applied -+ (cap_t + cap_m), else 0. Gauge 1:
    the larger breakaway distance; gauge 2: forward less backward."""
    t_fwd, m_fwd = torque - cap_t, moment - cap_m
    forward = t_fwd + (m_fwd - back_loss * m_fwd if m_fwd > 0.0 else m_fwd + fwd_loss * m_fwd)
    t_back, m_back = torque + cap_t, moment + cap_m
    backward = -t_back - (m_back - back_loss * m_back if m_back < 0.0 else m_back + fwd_loss * m_back)
    if gauge > 0.0:
        return max(forward, backward) if gauge < 1.5 else forward - backward
    applied, cap = torque + moment, cap_t + cap_m
    return applied - cap if forward > 0.0 else (applied + cap if backward > 0.0 else 0.0)


def node_moment(P, j, v, applied):
    """The net moment on the full chain's intermediate node j: less its viscous friction and,
    with friction that holds, its Stribeck sliding law or, at v = 0, its stick law."""
    o = int(P[lo.NODE_FRIC])
    if o == 0:
        return applied
    b = o + lo.NF_STRIDE * (j - 1)
    applied -= P[b + lo.NF_VISC] * v
    ts = P[b + lo.NF_TS]
    if ts > 0.0 and P[lo.STICK] > 0.0:
        if v == 0.0:
            return stuck_or_breaking(applied, ts)
        return applied - slip_friction(v, P[b + lo.NF_TC], ts, P[b + lo.NF_INV_VS], P[b + lo.NF_DIR])
    return applied


# --- the drivetrain's compliance and loss (compliance.h) -------------------------------------

def contact(tau_c, tau_d):
    """Modelica ElastoBacklash: spring part tau_c (0 inside the play), damper part tau_d;
    on the positive side tau_c + min(tau_c, tau_d), 0 where that would pull; mirrored."""
    if tau_c > 0.0:
        return 0.0 if tau_c + tau_d <= 0.0 else tau_c + min(tau_c, tau_d)
    if tau_c < 0.0:
        return 0.0 if tau_c + tau_d >= 0.0 else tau_c + max(tau_c, tau_d)
    return 0.0


def beyond_play(d, c):
    """The deflection beyond a half play c."""
    return d - c if d > c else (d + c if d < -c else 0.0)


def segment_force(k, d, dd, c, beta):
    """A compliance's force and its spring's deflection beyond the play."""
    if c <= B_EPS:
        return k * d + beta * k * dd, d
    z = beyond_play(d, c)
    return contact(k * z, beta * k * dd), z


def blend(P, sg):
    """The loss coefficient at the power flow's smooth sign sg: ETA_MEAN sg + ETA_HALF a(sg),
    a = sg^2, or near self-locking (ETA_MEAN < 2 |ETA_HALF|) the rounded |sg| whose steepest
    slope is r = ETA_MEAN / |ETA_HALF|."""
    mean, half = P[lo.ETA_MEAN], P[lo.ETA_HALF]
    a = sg * sg
    if mean < 2.0 * abs(half):
        r = mean / abs(half)
        w2 = r * (2.0 - r) / max((r - 1.0) * (r - 1.0), 1e-300)
        a *= (math.sqrt(1.0 + w2) + 1.0) / (math.sqrt(1.0 + w2 * a) + 1.0)
    return mean * sg + half * a


def loss_coefficient(P, nts, jd, n, rest, sw):
    """c from the sign of the torque passed on past the members before the loss (inertia
    J_w = JW n^2), T = ((jd - J_w) nts - J_w rest) / J_d(q0), and the speed's smooth sign sw."""
    if P[lo.ETA_MEAN] <= 0.0:
        return 0.0
    jw = P[lo.JW] * n * n
    passed = ((jd - jw) * nts - jw * rest) * P[lo.INV_JD0]
    return blend(P, smooth_sign(passed * P[lo.INV_TAU_S]) * sw)


def lossy(P, nts, jd, djd, n, dn, rest, sw):
    """The motor side's (N tau, J, J') with the loss: N tau and J_w scaled by 1 - c."""
    if P[lo.ETA_MEAN] <= 0.0:
        return nts, jd, djd
    c = loss_coefficient(P, nts, jd, n, rest, sw)
    return nts - c * nts, jd - c * P[lo.JW] * n * n, djd - c * 2.0 * P[lo.JW] * n * dn


def chain_accelerations(p, pd, q, qd, nts, jd, djd, n, m_load, P, T, x, dx, sw):
    """The full chain: nodes 0 (p), 1..NMID (in x from OFF_NODE), NMID + 1 (q); Lagrange's
    equations of T = sum J_j(p) y_j'^2 / 2, V = sum k_s(p) z_s^2 / 2 with one loss
    coefficient c (node inertias J_j - c J_w,j, torque (1 - c) N tau, segment weights
    1 - c l_s). Writes the intermediate nodes' derivatives, returns (p'', q'')."""
    nm, o, g = int(P[lo.NMID]), int(P[lo.OFF_NODE]), int(P[lo.OFF_SEG])
    ks = P[lo.KSCALE]

    def node_inertia(j, c):
        r = int(P[lo.ROW_NODE]) + lo.NODE_ROWS * (j - 1)
        jj, dj = row_at(P, T, r, p)
        if c != 0.0:
            jw, djw = row_at(P, T, r + 2, p)
            jj, dj = jj - c * jw, dj - c * djw
        return jj, dj

    k0, dk0 = row_at(P, T, lo.T_K, p)
    k0, dk0 = k0 * ks, dk0 * ks
    f0, z0 = segment_force(k0, p - x[o], pd - x[o + 1], P[g + lo.SEG_PLAY], P[g + lo.SEG_BETA])
    c = loss_coefficient(P, nts, jd, n, -f0 - 0.5 * dk0 * z0 * z0, sw)
    w0 = 1.0 - c * P[g + lo.SEG_LOSS]
    potential = -0.5 * w0 * dk0 * z0 * z0
    kinetic = 0.0
    f_in = w0 * f0
    for j in range(1, nm + 1):
        a = o + 2 * (j - 1)
        y, yd = x[a], x[a + 1]
        yn, ynd = (x[a + 2], x[a + 3]) if j < nm else (q, qd)
        jj, dj = node_inertia(j, c)
        kinetic += 0.5 * dj * yd * yd
        kj, dkj = row_at(P, T, lo.T_KS + 2 * (j - 1), p)
        kj, dkj = kj * ks, dkj * ks
        gj = g + lo.SEG_STRIDE * j
        fj, zj = segment_force(kj, y - yn, yd - ynd, P[gj + lo.SEG_PLAY], P[gj + lo.SEG_BETA])
        wj = 1.0 - c * P[gj + lo.SEG_LOSS]
        potential -= 0.5 * wj * dkj * zj * zj
        dx[a] = yd
        dx[a + 1] = node_moment(P, j, yd, f_in - wj * fj - dj * pd * yd) / jj
        f_in = wj * fj
    jl, djl = node_inertia(nm + 1, c)
    kinetic += 0.5 * djl * qd * qd
    qdd = (f_in + m_load - djl * pd * qd) / jl
    jw0, djw0 = row_at(P, T, int(P[lo.ROW_JW0]), p) if c != 0.0 else (0.0, 0.0)
    pdd = (((1.0 - c) * nts - 0.5 * (djd - c * djw0) * pd * pd + kinetic - w0 * f0 + potential)
           / (jd - c * jw0))
    return pdd, qdd


# --- the right-hand side ----------------------------------------------------------------------

def electrics(t, x, P, T, iref_held, wm, q, cur, xi, dx):
    """The controller and the armature: (di, dxi, i, v, i_ref)."""
    mode = int(P[lo.CMODE])
    if mode == lo.OPEN_LOOP:
        v = clip(P[lo.V_OPEN] + (command(t, P) - P[lo.REF_OFF]), P[lo.VLIM])
        if P[lo.L] > 0.0:
            return (v - P[lo.R] * cur - P[lo.KE] * wm) * P[lo.INV_L], 0.0, cur, v, 0.0
        return 0.0, 0.0, (v - P[lo.KE] * wm) / P[lo.R], v, 0.0
    if mode == lo.CONTINUOUS:
        r, i_ff, w_ff = continuous_command(t, P, T)
        unclamped = motion_controller(x, P, (r, q, wm - w_ff), dx) + i_ff
        iref = clip(unclamped, P[lo.ILIM])
        aw = int(P[lo.AW])
        if aw > 0 and iref != unclamped:
            # back-calculation while clamped: xc' += g Kaw (clamped - unclamped), the
            # integrator's direction g at P[AW:AW+nc], the tracking gain Kaw after it
            nc = int(P[lo.NC])
            for j in range(nc):
                dx[lo.NX_PHYS + j] += P[aw + j] * (P[aw + nc] * (iref - unclamped))
    else:
        iref = iref_held
    if P[lo.L] > 0.0:
        e = iref - cur
        vc = P[lo.KPI] * e + xi
        v = clip(vc, P[lo.VLIM])
        di = (v - P[lo.R] * cur - P[lo.KE] * wm) * P[lo.INV_L]
        return di, P[lo.KII] * e + (v - vc) * P[lo.KAW], cur, v, iref  # back-calculation
    v = clip(P[lo.R] * iref + P[lo.KE] * wm, P[lo.VLIM])
    return 0.0, 0.0, (v - P[lo.KE] * wm) / P[lo.R], v, iref


def load_moment(P, ql, qld, stick):
    """Hinge moment, stiffness and damping, the stroke-end stop and the load's sliding friction."""
    m = -P[lo.HINGE_M] - P[lo.HINGE_K] * ql - P[lo.HINGE_D] * qld
    if P[lo.STROKE_MODE] == lo.STROKE_STOP:
        if ql > P[lo.STROKE_HI]:
            m += min(-P[lo.KSTOP] * (ql - P[lo.STROKE_HI]) - P[lo.DSTOP] * qld, 0.0)
        elif ql < P[lo.STROKE_LO]:
            m += max(-P[lo.KSTOP] * (ql - P[lo.STROKE_LO]) - P[lo.DSTOP] * qld, 0.0)
    if stick and qld != 0.0 and P[lo.TS_L] > 0.0:
        m -= slip_friction(qld, P[lo.TC_L], P[lo.TS_L], P[lo.INV_VS_L], P[lo.DIR_L])
    return m


def rhs(t, x, P, T, iref_held, dx, aux):
    """dx/dt of the closed loop at (t, x) into ``dx``; current, voltage, i_ref and motor
    torque into ``aux`` (the compiled ``rhs``'s contract)."""
    for j in range(lo.NX_PHYS, len(x)):
        dx[j] = 0.0  # sampled controller and estimator states are held
    p, pd, q, qd, cur, xi, s = (float(x[j]) for j in range(lo.NX_PHYS))
    jd, djd = row_at(P, T, lo.T_J, p)
    n, dn = row_at(P, T, lo.T_N, p)
    wm = n * pd
    di, dxi, cur, v, iref = electrics(t, x, P, T, iref_held, wm, q, cur, xi, dx)
    tau = P[lo.KT] * cur
    stick = P[lo.STICK] > 0.0
    tw = smooth_sign(wm * P[lo.WS])
    if stick:
        fm = 0.0 if pd == 0.0 else slip_friction(wm, P[lo.TC], P[lo.TS_M], P[lo.INV_VS_M], P[lo.DIR_M])
    else:
        fm = P[lo.TC] * tw
    sw = tw if n >= 0.0 else -tw  # the output speed's smooth sign
    nts = n * (tau - P[lo.BM] * wm - fm)
    rigid = P[lo.RIGID] > 0.0
    m_load = load_moment(P, p if rigid else q, pd if rigid else qd, stick)
    hold = (n * P[lo.TS_M], P[lo.HOLD_FWD], P[lo.HOLD_BACK], P[lo.HOLD_GAUGE])
    if rigid:
        nts, jd, djd = lossy(P, nts, jd, djd, n, dn, m_load, sw)
        if P[lo.CAM] > 0.0:
            o = int(P[lo.CAM])
            pdd = shaft_acceleration(P[o:o + lo.NCAM], p, pd, nts + m_load, jd, 0.5 * djd * pd * pd, n * P[lo.WS])
            if stick and pd == 0.0:
                pdd = gear_at_rest(nts, pdd * jd - nts, hold[0], P[lo.TS_L], *hold[1:]) / jd
        else:
            m_p = nts - 0.5 * djd * pd * pd + m_load
            if stick and pd == 0.0:
                m_p = gear_at_rest(nts, m_load, hold[0], P[lo.TS_L], *hold[1:])
            pdd = m_p / jd
        qdd = pdd
        rates = (pd, pdd, pd, pdd)
    elif P[lo.NMID] > 0.0:
        pdd, qdd = chain_accelerations(p, pd, q, qd, nts, jd, djd, n, m_load, P, T, x, dx, sw)
        if stick:  # lossless at rest: each end sticks within its own breakaway level
            if pd == 0.0:
                pdd = gear_at_rest(pdd * jd, 0.0, hold[0], 0.0, 0.0, 0.0, hold[3]) / jd
            if qd == 0.0 and P[lo.TS_L] > 0.0:
                qdd = gear_at_rest(qdd / P[lo.INV_JL], 0.0, P[lo.TS_L], 0.0, 0.0, 0.0, hold[3]) * P[lo.INV_JL]
        rates = (pd, pdd, qd, qdd)
    else:
        k, dk = row_at(P, T, lo.T_K, p)
        k, dk = k * P[lo.KSCALE], dk * P[lo.KSCALE]
        c, beta, dd = P[lo.HALF_PLAY], P[lo.BETA], pd - qd
        if P[lo.PAPER] > 0.0:  # the cam paper's play operator: the spring on s - q
            z = s - q
            f = k * z + (beta * k * dd if abs(p - s) >= c * (1.0 - 1e-9) else 0.0)
        else:
            f, z = segment_force(k, p - q, dd, c, beta)
        spring = -f - 0.5 * dk * z * z  # the compliance's moment on the motor side
        nts, jd, djd = lossy(P, nts, jd, djd, n, dn, spring, sw)
        m_p = nts - 0.5 * djd * pd * pd - f - 0.5 * dk * z * z
        m_q = f + m_load
        if stick:
            if pd == 0.0:
                m_p = gear_at_rest(nts, spring, hold[0], 0.0, *hold[1:])
            if qd == 0.0 and P[lo.TS_L] > 0.0:
                m_q = gear_at_rest(m_q, 0.0, P[lo.TS_L], 0.0, 0.0, 0.0, hold[3])
        rates = (pd, m_p / jd, qd, m_q * P[lo.INV_JL])
    for j, value in enumerate(rates):
        dx[j] = value
    dx[4], dx[5], dx[6] = di, dxi, 0.0
    aux[lo.AUX_I], aux[lo.AUX_V], aux[lo.AUX_IREF], aux[lo.AUX_TAU] = cur, v, iref, tau
