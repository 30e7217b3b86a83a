"""The compiled right-hand side and the controller sample update (numba, flat arrays).

One physics, used by every integrator (fixed-step RK4, the cam paper's scheme, scipy's
``solve_ivp``, python-control and the Jacobian estimate): :func:`rhs` and
:func:`controller_sample`. Layout of ``x`` and ``P`` in :mod:`servo_toolkit.sim.layout`.

Equations (generalized coordinates p, q at the output; N(p) motor rad per output rad)::

    J_d(p) p'' + J_d'(p) p'^2 / 2 = N(p) tau_m - f - K'(p) z^2 / 2
    J_L q''                       = f + M_hinge(q, q') + M_stop(q, q')
    (rigid chain ending in a cam, q the cam angle: J(q) q'' + J'(q) q'^2 / 2
     = N tau_m + M_hinge - M_g, M_g = (sigma f - G_x) ds/dq the follower's weight and guide
     friction, seed 002 eqs 1 and 3, sigma = sign(ds/dq) tanh(omega_m / w_s))
    tau_m = Kt i - b omega_m - Tc tanh(omega_m / w_s),   omega_m = N(p) p'
    (with the drivetrain's loss, :func:`lossy`: N tau_m and the inertia before the losses,
     J_w, scale by 1 - c; the rest of J_d is as it is)
    L i' = v - R i - Ke omega_m                          (or i = (v - Ke omega_m) / R, L = 0)

with the elasto-backlash contact law of Modelica's ``ElastoBacklash`` (:func:`contact`):
deflection d = p - q, play +-c, penetration z = d -+ c beyond the play, spring part
tau_c = K z, damper part tau_d = beta K d', and on the positive side
f = tau_c + min(tau_c, tau_d) if tau_c + tau_d > 0 else 0 (mirrored on the negative side;
f = 0 inside the play; with no play, f = tau_c + tau_d). The damper part is bounded by the spring part, |f - tau_c| <= |tau_c|,
so f is continuous at engagement (f -> 0 as z -> 0 at any d') and never pulls. The potential
K(p) z^2 / 2 gives the K'(p) term, so the undamped drivetrain conserves energy exactly and
the damped one never gains energy. A rigid chain uses J(p) = J_d + J_L and q = p.

Current loop: PI with voltage clamp and back-calculation anti-windup,
xi' = Kii e + (v - v_c) Kii / Kpi (tracking time constant = the integral time Kpi / Kii):
continuous in the state, so adaptive solvers integrate through saturation.
"""

from __future__ import annotations

import math

import numba as nb

from ..core.jit_cache import install as _install_cache

_install_cache()  # noqa: E402 - before any kernel below is decorated

from ..components.cam.kernels import shaft_acceleration  # noqa: E402
from .vmath import FASTMATH, inline, tanh  # noqa: E402 - the flags, and the friction's branch-free tanh
from .tables import cell, hermite, interp  # noqa: E402,F401 - hermite: the tables' interpolation for callers
from .compliance_kernel import B_EPS, chain_accelerations, contact, lossy, speed_sign  # noqa: E402,F401
from .friction_kernel import gear_at_rest, slip_friction, stick_moments, stick_nodes  # noqa: E402

from .layout import (EST, EST_DIFFERENCE, INV_TS, LSB_M, OFF_E, OFF_KF, T_M, AUX_I, AUX_IREF,
                     AUX_TAU, AUX_V, BETA, BM, CMODE, CONTINUOUS, DSTOP, HALF_PLAY, HINGE_D,
                     HINGE_K, HINGE_M, ILIM, KE, KII, KPI, KSCALE, KSTOP, KT, KAW, L, CAM, NCAM,
                     LSB, NC, NX_PHYS, OFF_A, OFF_B, OFF_C, OFF_D, OPEN_LOOP, PAPER, PERIODIC, R,
                     REF_OFF, RIGID,
                     STROKE_HI, STROKE_LO, STROKE_MODE, STROKE_STOP, T_J, T_K, T_N, TAB_H, TAB_LO,
                     TAB_N, TC, V_OPEN, VLIM, WS, INV_H, INV_L, INV_JL, STICK, TS_M, INV_VS_M, TC_L,
                     TS_L, INV_VS_L, NMID, FF_ON, AW, DIR_M, DIR_L, HOLD_FWD, HOLD_BACK,
                     HOLD_GAUGE)
# the reference r(t) and its command: the controller's and the lanes' (which import them from here)
from .command_kernel import command, reference, schedule_factors  # noqa: E402
from .feedforward_kernel import feedforward  # noqa: E402

jit = nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy")


@inline
def clip(v, lim):
    """Clamp v to [-lim, lim]."""
    if v > lim:
        return lim
    if v < -lim:
        return -lim
    return v


@inline
def _motion(x, P, r, th, wm, dx, base, write_state):
    """Motion controller: output i_ref (unclamped); state update or derivative into dx."""
    nc = int(P[NC])
    oa, ob, oc, od = int(P[OFF_A]), int(P[OFF_B]), int(P[OFF_C]), int(P[OFF_D])
    y = P[od] * r + P[od + 1] * th + P[od + 2] * wm
    for j in range(nc):
        y += P[oc + j] * x[NX_PHYS + j]
    if write_state:
        for j in range(nc):
            acc = P[ob + 3 * j] * r + P[ob + 3 * j + 1] * th + P[ob + 3 * j + 2] * wm
            for k in range(nc):
                acc += P[oa + j * nc + k] * x[NX_PHYS + k]
            dx[base + j] = acc
    return y


@inline
def motion_columns(X, P, r, th, wm, y, xn, w):
    """:func:`_motion` (sampled: output and next state) for ``w`` controllers side by side,
    controller l in column l of ``X`` (states at rows NX_PHYS..) and ``P`` (parameters), its
    inputs ``r[l]``, ``th[l]``, ``wm[l]``; output into ``y[l]``, next states into
    ``xn[j, l]``. Every column takes the sums of :func:`_motion` in their order (the same
    value to the last bit under the same flags); the loops across columns are innermost, so
    they vectorize. The controller's structure (size and offsets) is column 0's: every
    column must share it.
    """
    nc = int(P[NC, 0])
    oa, ob, oc, od = int(P[OFF_A, 0]), int(P[OFF_B, 0]), int(P[OFF_C, 0]), int(P[OFF_D, 0])
    for l in range(w):
        y[l] = P[od, l] * r[l] + P[od + 1, l] * th[l] + P[od + 2, l] * wm[l]
    for j in range(nc):
        for l in range(w):
            y[l] += P[oc + j, l] * X[NX_PHYS + j, l]
    for j in range(nc):
        for l in range(w):
            xn[j, l] = P[ob + 3 * j, l] * r[l] + P[ob + 3 * j + 1, l] * th[l] + P[ob + 3 * j + 2, l] * wm[l]
        for k in range(nc):
            for l in range(w):
                xn[j, l] += P[oa + j * nc + k, l] * X[NX_PHYS + k, l]


@inline
def measured_angle(q, P):
    """Output encoder: q rounded to the encoder's least significant bit (0 = ideal)."""
    lsb = P[LSB]
    if lsb > 0.0:
        return lsb * math.floor(q / lsb + 0.5)
    return q


@inline
def motor_angle(P, T, p):
    """Motor angle (rad, 0 at mid-stroke) at motor-side position p; periodic tables add one
    table period's motor travel per wrap."""
    val, _ = hermite(T, T_M, P, p)
    if P[PERIODIC] > 0.0:
        last = P[TAB_N] - 1.0
        wraps = math.floor((p - P[TAB_LO]) * P[INV_H] / last)
        val += wraps * (T[T_M, int(last)] - T[T_M, 0])
    return val


@inline
def measured_motor_angle(P, T, p):
    """Motor encoder: the motor angle rounded to the encoder's count (0 = unquantized)."""
    th = motor_angle(P, T, p)
    lsb = P[LSB_M]
    if lsb > 0.0:
        return lsb * math.floor(th / lsb + 0.5)
    return th


@inline
def speed_estimate(x, P, T, wm_true):
    """Motor speed for the speed loop: the true speed ("ideal"), or an estimate from the
    motor encoder updated once per sample (its states follow the controller's in x).

    "difference": (z_k - z_{k-1}) / Ts. "kalman": constant-gain filter, predict x <- F x,
    update x <- x + K (z - x[0]) (the measurement is the angle, H = [1, 0, 0]).
    """
    est = int(P[EST])
    if est == 0:
        return wm_true
    z = measured_motor_angle(P, T, x[0])
    e = int(P[OFF_E])
    if est == EST_DIFFERENCE:
        wm = (z - x[e]) * P[INV_TS]
        x[e] = z
        x[e + 1] = wm
        return wm
    o = int(P[OFF_KF])
    a0, a1, a2 = x[e], x[e + 1], x[e + 2]
    p0 = P[o] * a0 + P[o + 1] * a1 + P[o + 2] * a2
    p1 = P[o + 3] * a0 + P[o + 4] * a1 + P[o + 5] * a2
    p2 = P[o + 6] * a0 + P[o + 7] * a1 + P[o + 8] * a2
    inn = z - p0
    x[e] = p0 + P[o + 9] * inn
    x[e + 1] = p1 + P[o + 10] * inn
    x[e + 2] = p2 + P[o + 11] * inn
    return x[e + 1]


@jit  # called once per sample, not per step: compiled once, shared by every loop and Python
def controller_sample(t, x, P, T, work):
    """Sampled motion controller at time t: returns the held i_ref, updates x[NX_PHYS:]
    (:func:`controller_update` at the reference r(t), plus the feedforward current along
    r(t), r'(t), r''(t) when ``FF_ON``: once per sample, never per integration stage)."""
    if P[FF_ON] > 0.0:
        r, i_ff, w_ff = feedforward(t, P, T)
        return controller_update(r, x, P, T, work, i_ff, w_ff)
    return controller_update(reference(t, P), x, P, T, work, 0.0, 0.0)


@jit  # a call, not inlined into every copy of the right-hand side: compiled once
def continuous_command(t, P, T):
    """The continuous controller's reference and feedforward at time t, ``(r, i_ff, w_ff)``
    (:func:`feedforward` when ``FF_ON``, else ``(r(t), 0, 0)``)."""
    if P[FF_ON] > 0.0:
        return feedforward(t, P, T)
    return reference(t, P), 0.0, 0.0


@inline
def controller_inputs(x, P, T):
    """The motion controller's measurements at the state x: the output angle as the output
    encoder reads it and the motor speed, true or estimated (:func:`speed_estimate`, whose
    states in x are updated)."""
    n, _ = hermite(T, T_N, P, x[0])
    wm = speed_estimate(x, P, T, n * x[1])
    return measured_angle(x[2], P), wm


@inline
def controller_update(r, x, P, T, work, i_ff, w_ff):
    """The sample of :func:`controller_sample` at a given reference r: returns the held i_ref
    (the motion controller's output plus the feedforward current ``i_ff``, clamped at the
    current limit), updates x[NX_PHYS:]. The speed loop sees the measured motor speed less
    the feedforward's speed reference ``w_ff`` (0 without one). A gain schedule
    (``SCHED``) scales the controller's position-error inputs and its speed input by its
    factors at the measured output angle (:func:`~.command_kernel.schedule_factors`). With
    back-calculation gains (``AW``: every sampled controller with an integrator) a clamped
    sample moves the controller's integrator by the clamp's excess (its next output starts
    at the limit: the integral does not wind up while the current is limited, whether the
    feedback or a feedforward's share holds the limit).

    The output angle is quantized by the output encoder; the motor speed is the true
    omega_m or, per the model's speed estimator, an estimate from the (quantized) motor
    encoder (:func:`controller_inputs`).
    """
    nc = int(P[NC])
    th, wm = controller_inputs(x, P, T)
    ge, gw = schedule_factors(P, th)
    y = _motion(x, P, ge * r, ge * th, gw * (wm - w_ff), work, 0, True) + i_ff
    o = int(P[AW])
    if o > 0 and abs(y) > P[ILIM]:
        # back-calculation at the clamp: the controller's integrator takes the excess, so it
        # does not wind up while the current is limited
        excess = clip(y, P[ILIM]) - y
        for j in range(nc):
            work[j] += P[o + j] * excess
    for j in range(nc):
        x[NX_PHYS + j] = work[j]
    return clip(y, P[ILIM])


@inline
def rhs_phys(t, p, pd, q, qd, cur, xi, s, P, T, iref_held, x, dx, lanes, holds):
    """dx/dt of the physical states (x[0:7] passed as scalars), returned as scalars.

    Returns ``(p', pd', q', qd', i', xi', i, v, i_ref, tau_m)``; s' = 0. Only the continuous
    motion controller and the full chain's intermediate nodes touch the arrays: they read
    their states in ``x[NX_PHYS:]`` and write their derivatives into ``dx[NX_PHYS:]``
    (nothing else is written; a continuous controller with back-calculation gains, ``AW``,
    adds ``Kaw g (clamped - unclamped)`` to its derivative while its output is clamped, a
    law continuous in the state, like the current PI's). Scalars in and out let the
    fixed-step loop keep the physical state in registers.

    ``lanes`` (a compile-time constant at each call) is True in the batched kernel's loop
    across variants (:mod:`.batch_lanes`), whose caller guarantees a sampled or open-loop
    controller, the two-mass chain and no cam: the other code is left out there (a vectorized
    loop evaluates every branch and selects, so a branch left out is time saved), and that
    loop is branch- and call-free and vectorizes. Every other caller passes False. ``holds`` (also a
    compile-time constant) compiles in friction that holds (``STICK``): every caller but the
    lanes of a block without it passes True. In the lanes its stick and breakaway law are
    selects, and the caller splits a lane's step at a speed reversal as the single run does.
    """
    kc, tc = cell(P, p)
    hc = P[TAB_H]
    ih = P[INV_H]
    jd, djd = interp(T, T_J, kc, tc, hc, ih)
    n, dn = interp(T, T_N, kc, tc, hc, ih)
    wm = n * pd
    mode = int(P[CMODE])
    # --- controller and electrics
    if mode == OPEN_LOOP:
        iref = 0.0
        # a constant voltage, plus a sine (its kernel command about REF_OFF, never shaped) for a dwell
        # (the lanes pass the command's part in ``iref_held``: evaluated once per lane outside
        # their vectorized loop, which would otherwise evaluate its sine in every lane)
        v = clip(P[V_OPEN] + (iref_held if lanes else command(t, P) - P[REF_OFF]), P[VLIM])
        if P[L] > 0.0:
            di = (v - P[R] * cur - P[KE] * wm) * P[INV_L]
        else:
            cur = (v - P[KE] * wm) / P[R]
            di = 0.0
        dxi = 0.0
    else:
        if not lanes and mode == CONTINUOUS:
            r, i_ff, w_ff = continuous_command(t, P, T)
            y = _motion(x, P, r, q, wm - w_ff, dx, NX_PHYS, True) + i_ff
            iref = clip(y, P[ILIM])
            o = int(P[AW])
            if o > 0 and iref != y:
                # continuous back-calculation: the integral bleeds the clamp's excess at Kaw
                nc = int(P[NC])
                bleed = P[o + nc] * (iref - y)
                for j in range(nc):
                    dx[NX_PHYS + j] += P[o + j] * bleed
        else:
            iref = iref_held
        if P[L] > 0.0:
            e = iref - cur
            vc = P[KPI] * e + xi
            v = clip(vc, P[VLIM])
            di = (v - P[R] * cur - P[KE] * wm) * P[INV_L]
            # back-calculation anti-windup: continuous, bleeds the clamp excess off the integral
            dxi = P[KII] * e + (v - vc) * P[KAW]
        else:
            v = clip(P[R] * iref + P[KE] * wm, P[VLIM])
            cur = (v - P[KE] * wm) / P[R]
            di = 0.0
            dxi = 0.0
    tau = P[KT] * cur
    # friction: exact stick (STICK; branch-free, so the lanes vectorize it) or the smooth Coulomb model
    stick = holds and P[STICK] > 0.0
    tw = tanh(wm * P[WS])  # the motor speed's smooth sign: the smooth Coulomb friction's and the loss's
    if stick:
        fm = 0.0 if pd == 0.0 else slip_friction(wm, P[TC], P[TS_M], P[INV_VS_M], P[DIR_M])
    else:
        fm = P[TC] * tw
    sw = speed_sign(n, tw)
    tau_shaft = tau - P[BM] * wm - fm
    nts = n * tau_shaft
    # --- load side: hinge moment, stroke-end stop, the load's friction while it slides
    if not lanes and P[RIGID] > 0.0:
        ql, qld = p, pd
    else:
        ql, qld = q, qd
    m_load = -P[HINGE_M] - P[HINGE_K] * ql - P[HINGE_D] * qld
    if P[STROKE_MODE] == STROKE_STOP:
        if ql > P[STROKE_HI]:
            m_load += min(-P[KSTOP] * (ql - P[STROKE_HI]) - P[DSTOP] * qld, 0.0)
        elif ql < P[STROKE_LO]:
            m_load += max(-P[KSTOP] * (ql - P[STROKE_LO]) - P[DSTOP] * qld, 0.0)
    if stick and qld != 0.0 and P[TS_L] > 0.0:
        m_load -= slip_friction(qld, P[TC_L], P[TS_L], P[INV_VS_L], P[DIR_L])
    if not lanes and P[RIGID] > 0.0:
        nts, jd, djd = lossy(P, nts, jd, djd, n, dn, m_load, sw)
        if not lanes and P[CAM] > 0.0:
            # chain ends in a cam: the follower's weight and guide friction load the shaft,
            # M_g = (sigma f - G_x) ds/dq (seed 002 eq 3; its m a part is in J and J')
            oc = int(P[CAM])
            pdd, _ = shaft_acceleration(P[oc:oc + NCAM], p, pd, nts + m_load, jd,
                                        0.5 * djd * pd * pd, n * P[WS])
            if stick and pd == 0.0:  # motor and load at rest on one node: held by the gear's band, or breaking away
                pdd = gear_at_rest(nts, pdd * jd - nts, n * P[TS_M], P[TS_L], P[HOLD_FWD], P[HOLD_BACK],
                                   P[HOLD_GAUGE]) / jd
        else:
            m_p = nts - 0.5 * djd * pd * pd + m_load
            if stick and pd == 0.0:  # motor and load at rest on one node: held by the gear's band, or breaking away
                m_p = gear_at_rest(nts, m_load, n * P[TS_M], P[TS_L], P[HOLD_FWD], P[HOLD_BACK], P[HOLD_GAUGE])
            pdd = m_p / jd
        return pd, pdd, pd, pdd, di, dxi, cur, v, iref, tau
    if not lanes and P[NMID] > 0.0:
        pdd, qdd = chain_accelerations(p, pd, q, qd, nts, jd, djd, n, dn, m_load, kc, tc, P, T, x, dx, sw)
        if stick:
            pdd, qdd = stick_nodes(pdd, qdd, pd, qd, jd, n, P)
        return pd, pdd, qd, qdd, di, dxi, cur, v, iref, tau
    # --- compliance with backlash
    k, dk = interp(T, T_K, kc, tc, hc, ih)
    k *= P[KSCALE]
    dk *= P[KSCALE]
    c = P[HALF_PLAY]
    dd = pd - qd
    if P[PAPER] > 0.0:
        # the cam paper's play operator: the spring acts on s - q, s held inside the play
        z = s - q
        f = k * z
        if abs(p - s) >= c * (1.0 - 1e-9):  # in contact (s was pushed to p -+ c)
            f += P[BETA] * k * dd
    elif c <= B_EPS:
        # no play (Modelica: b <= 1e-10 rad): a plain spring-damper, which may pull
        z = p - q
        f = k * z + P[BETA] * k * dd
    else:
        d = p - q
        if d > c:
            z = d - c
        elif d < -c:
            z = d + c
        else:
            z = 0.0
        f = contact(k * z, P[BETA] * k * dd)
    nts, jd, djd = lossy(P, nts, jd, djd, n, dn, -f - 0.5 * dk * z * z, sw)
    m_p = nts - 0.5 * djd * pd * pd - f - 0.5 * dk * z * z  # the moments on the motor side and the load
    m_q = f + m_load
    if stick:
        m_p, m_q = stick_moments(m_p, m_q, pd, qd, n, nts, -f - 0.5 * dk * z * z, P)
    return pd, m_p / jd, qd, m_q * P[INV_JL], di, dxi, cur, v, iref, tau


#: the serial right-hand side's compilation: without the runtime's reference counting (it
#: allocates nothing), whose atomic increments and decrements of the arrays it binds took
#: most of a step's time when inlined into a loop
serial_jit = nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)


@serial_jit
def rhs_phys_serial(t, p, pd, q, qd, cur, xi, s, P, T, iref_held, x, dx):
    """:func:`rhs_phys` outside the vectorized lanes, compiled once as a function of its own:
    the kernels that are not the fixed-step loop's hot path (the array form :func:`rhs`, the
    cam paper's scheme, Jacobians, the stiff reference solver) call it instead of inlining
    their own copy, which would compile the whole right-hand side again for each."""
    return rhs_phys(t, p, pd, q, qd, cur, xi, s, P, T, iref_held, x, dx, False, True)


@jit
def rhs(t, x, P, T, iref_held, dx, aux):
    """dx/dt of the closed loop; ``aux`` receives current, voltage, i_ref and motor torque."""
    for j in range(NX_PHYS, x.size):  # sampled controller and estimator states are held
        dx[j] = 0.0
    d0, d1, d2, d3, d4, d5, cur, v, iref, tau = rhs_phys_serial(t, x[0], x[1], x[2], x[3], x[4], x[5],
                                                                x[6], P, T, iref_held, x, dx)
    dx[0] = d0
    dx[1] = d1
    dx[2] = d2
    dx[3] = d3
    dx[4] = d4
    dx[5] = d5
    dx[6] = 0.0
    aux[AUX_I] = cur
    aux[AUX_V] = v
    aux[AUX_IREF] = iref
    aux[AUX_TAU] = tau
