"""The drivetrain's compliances and losses inside the compiled kernels: the elasto-backlash
contact law, a compliance's force, the loss coefficient and its folding into the motor side's
equation, and the full chain's node accelerations (the equations in
:mod:`servo_toolkit.sim.kernel` and :mod:`servo_toolkit.sim.chain_model`)."""

from __future__ import annotations

import math

from ..core.jit_cache import install as _install_cache

_install_cache()  # noqa: E402 - before any kernel below is decorated

from .layout import (ETA_HALF, ETA_MEAN, INV_H, INV_JD0, INV_TAU_S, JL, JW, KSCALE, NMID,  # noqa: E402
                     NODE_ROWS, OFF_NODE, OFF_SEG, ROW_JW0, ROW_NODE, SEG_BETA, SEG_LOSS, SEG_PLAY,
                     SEG_STRIDE, T_K, T_KS, TAB_H)
from .friction_kernel import node_moment  # noqa: E402
from .tables import interp  # noqa: E402
from .vmath import inline, tanh  # noqa: E402

#: half plays at or below this (rad) act as a plain spring-damper (Modelica's bEps = 1e-10 rad
#: total backlash)
B_EPS = 0.5e-10


@inline
def contact(tau_c, tau_d):
    """Modelica ``ElastoBacklash`` contact moment from the spring part ``tau_c = K z`` (sign =
    contact side, 0 inside the play) and the damper part ``tau_d = beta K d'``.

    Positive side: 0 if tau_c + tau_d <= 0 (no pulling), else tau_c + min(tau_c, tau_d);
    negative side mirrored. Continuous in z (|f| <= 2 |tau_c|), no events.
    """
    if tau_c > 0.0:
        if tau_c + tau_d <= 0.0:
            return 0.0
        return tau_c + min(tau_c, tau_d)
    if tau_c < 0.0:
        if tau_c + tau_d >= 0.0:
            return 0.0
        return tau_c + max(tau_c, tau_d)
    return 0.0


@inline
def loss_coefficient(P, nts, jd, n, rest, sw):
    """The drivetrain's loss coefficient c at this state: 1 - eta driving, 1 - 1/eta_b
    back-driven (negative), blended by the smooth signs of the transmitted torque and of the
    speed (c T p' >= 0: the loss never supplies power); 0 for a lossless chain. ``sw`` is the
    speed's smooth sign tanh(|N| p' / w_s) (:func:`speed_sign`: the Coulomb friction's
    tanh(omega_m / w_s) times the sign of N, one evaluation for both).

    The sign of the transmitted torque T is that of the lossless torque passed on past the
    members before the losses (rotor, pinion: inertia J_w = JW n^2 at the output),
    T = nts - J_w p'' with jd p'' = nts + rest, computed without its velocity terms (of the
    order of the ratio's variation) and times jd / J_d(q0) (the same sign; the scale of the
    smooth sign varies with J_d(p) / J_d(q0), a few per cent along a stroke).
    """
    if P[ETA_MEAN] <= 0.0:
        return 0.0
    jw = P[JW] * n * n
    t_free = ((jd - jw) * nts - jw * rest) * P[INV_JD0]
    return blend(P, tanh(t_free * P[INV_TAU_S]) * sw)


@inline
def blend(P, sg):
    """The loss coefficient at the smooth sign ``sg`` in [-1, 1] of the power flow:
    ``ETA_MEAN sg + ETA_HALF a(sg)``, 1 - eta at sg = 1 (driving), 1 - 1/eta_b at sg = -1
    (back-driven), smooth and monotone in sg, so that inside the smoothing band the loss stays
    between either mode's (1 - c >= eta > 0).

    a(sg) is an even, smooth |sg| with a(+-1) = 1: sg^2 (the quadratic blend) wherever that is
    monotone, r = ETA_MEAN / |ETA_HALF| >= 2 (1/eta_b - 1 <= 3 (1 - eta): every chain but a
    near-self-locking one); otherwise the rounded |sg| whose steepest slope is r,
    a = sg^2 (sqrt(1 + w^2) + 1) / (sqrt(1 + w^2 sg^2) + 1), w = sqrt(r (2 - r)) / (r - 1)
    (sqrt(sg^2 + e^2) - e scaled to 1 at +-1, e = 1/w; w = 0 is the quadratic). The quadratic
    there would overshoot 1 - eta, past 1 (a negative efficiency) near self-locking: 1.42 at
    eta = 0.29, eta_b = 0.1, where the motor side's inertia J_d - c J_w passes near zero.
    The quadratic costs one product (the branch is the same for every call of a model)."""
    mean, half = P[ETA_MEAN], P[ETA_HALF]
    a = sg * sg
    if mean < 2.0 * abs(half):
        r = mean / abs(half)
        w2 = r * (2.0 - r) / max((r - 1.0) * (r - 1.0), 1e-300)
        a *= (math.sqrt(1.0 + w2) + 1.0) / (math.sqrt(1.0 + w2 * a) + 1.0)
    return mean * sg + half * a


@inline
def speed_sign(n, tw):
    """The output speed's smooth sign tanh(|N| p' / w_s) from the motor speed's
    ``tw`` = tanh(N p' / w_s) (tanh is odd: the same value)."""
    return tw if n >= 0.0 else -tw


@inline
def lossy(P, nts, jd, djd, n, dn, rest, sw):
    """The drivetrain's loss (LossyGear-like) folded into the motor side's equation
    ``jd p'' = nts - djd p'^2 / 2 + rest``: returns its ``(nts, jd, djd)`` with the loss.

    The loss acts on the torque transmitted past the members before it (rotor, pinion:
    inertia J_w = JW n^2 at the output), T = nts - J_w p'' - J_w' p'^2 / 2, which loses
    c T (:func:`loss_coefficient`). Solved for p'': nts and J_w scale by (1 - c), the rest of
    the motor side stays.
    """
    if P[ETA_MEAN] <= 0.0:
        return nts, jd, djd
    c = loss_coefficient(P, nts, jd, n, rest, sw)
    return nts - c * nts, jd - c * P[JW] * n * n, djd - c * 2.0 * P[JW] * n * dn


@inline
def segment_force(k, d, dd, c, beta):
    """Force of a compliance of stiffness k with half play c and structural damping beta k at
    deflection d and rate dd (:func:`contact` beyond the play; a plain spring-damper without
    one). Returns the force and the spring's deflection beyond the play."""
    if c <= B_EPS:
        return k * d + beta * k * dd, d
    if d > c:
        z = d - c
    elif d < -c:
        z = d + c
    else:
        z = 0.0
    return contact(k * z, beta * k * dd), z


@inline
def node_inertia(P, T, j, c, kc, tc, hc, ih):
    """Node j's inertia at the motor-side position and its derivative along it, J_j - c J_w,j
    and J_j' - c J_w,j' (j = 1..NMID + 1: the intermediate nodes, then the load; c the
    loss coefficient, 0 for a lossless chain)."""
    r = int(P[ROW_NODE]) + NODE_ROWS * (j - 1)
    jj, dj = interp(T, r, kc, tc, hc, ih)
    if c != 0.0:
        jw, djw = interp(T, r + 2, kc, tc, hc, ih)
        jj -= c * jw
        dj -= c * djw
    return jj, dj


@inline
def inertia_beyond_motor(P, T, kc, tc, hc, ih):
    """The inertia of every node beyond the motor side and its derivative along p: the load
    side ``JL`` of a two-mass model, the sum of the further nodes' tables of the full chain."""
    nm = int(P[NMID])
    if nm == 0:
        return P[JL], 0.0
    total, slope = 0.0, 0.0
    for j in range(1, nm + 2):
        jj, dj = node_inertia(P, T, j, 0.0, kc, tc, hc, ih)
        total += jj
        slope += dj
    return total, slope


@inline
def chain_accelerations(p, pd, q, qd, nts, jd, djd, n, dn, m_load, kc, tc, P, T, x, dx, sw):
    """The full chain (``P[NMID]`` intermediate nodes, :mod:`servo_toolkit.sim.chain_model`):
    writes the intermediate nodes' derivatives into dx and returns ``(p'', q'')``.

    Node 0 is the motor side p, nodes 1..NMID the intermediate ones y_j, node NMID + 1 the
    load q. Every node's inertia J_j(p) is tabulated along the motor-side position (``jd``,
    ``djd`` for node 0), and segment s (between nodes s and s + 1) has its stiffness k_s(p),
    play and damper beta_s k_s(p) (:func:`segment_force`, force f_s, deflection beyond the
    play z_s). Lagrange's equations of T = sum_j J_j(p) y_j'^2 / 2 and
    V = sum_s k_s(p) z_s^2 / 2::

        J_0 p'' = N tau - J_0' p'^2 / 2 + sum_{j>0} J_j' y_j'^2 / 2 - f_0 - sum_s k_s' z_s^2 / 2
        J_j y_j'' = f_{j-1} - f_j - J_j' p' y_j'

    so the undamped, lossless chain conserves T + V exactly. The losses act where the chain
    has them, with one coefficient c for the whole chain (:func:`loss_coefficient`, judged
    at the motor side): node j's inertia J_j - c J_w,j (J_w,j its inertia before the
    losses, tabulated like J_j), the motor torque (1 - c) N tau and segment s weighted by
    1 - c l_s, l_s = (1 - eta / Pi_s) / (1 - eta) (driving: eta / Pi, the chain's
    driving-mode form). The power the losses take is then c times the power transmitted
    past the members before them. An intermediate node carrying a stage's friction
    (``NODE_FRIC``) slides against it and sticks at rest by its own breakaway level
    (:func:`~.friction_kernel.node_moment`).
    """
    nm = int(P[NMID])
    o = int(P[OFF_NODE])
    g = int(P[OFF_SEG])
    hc, ih, ks = P[TAB_H], P[INV_H], P[KSCALE]
    # segment 0: the motor side against node 1
    k0, dk0 = interp(T, T_K, kc, tc, hc, ih)
    k0 *= ks
    dk0 *= ks
    f0, z0 = segment_force(k0, p - x[o], pd - x[o + 1], P[g + SEG_PLAY], P[g + SEG_BETA])
    c = loss_coefficient(P, nts, jd, n, -f0 - 0.5 * dk0 * z0 * z0, sw)
    w0 = 1.0 - c * P[g + SEG_LOSS]
    pot = -0.5 * w0 * dk0 * z0 * z0  # -sum_s w_s k_s' z_s^2 / 2 on the motor side
    kin = 0.0  # sum_{j>0} J_j' y_j'^2 / 2 on the motor side
    f_in = w0 * f0  # the force the segment before node j passes on to it
    for j in range(1, nm + 1):  # the intermediate nodes
        a = o + 2 * (j - 1)
        y, yd = x[a], x[a + 1]
        if j < nm:
            yn, ynd = x[a + 2], x[a + 3]
        else:
            yn, ynd = q, qd
        jj, dj = node_inertia(P, T, j, c, kc, tc, hc, ih)
        kin += 0.5 * dj * yd * yd
        kj, dkj = interp(T, T_KS + 2 * (j - 1), kc, tc, hc, ih)
        kj *= ks
        dkj *= ks
        gj = g + SEG_STRIDE * j
        fj, zj = segment_force(kj, y - yn, yd - ynd, P[gj + SEG_PLAY], P[gj + SEG_BETA])
        wj = 1.0 - c * P[gj + SEG_LOSS]
        pot -= 0.5 * wj * dkj * zj * zj
        dx[a] = yd
        dx[a + 1] = node_moment(P, j, yd, f_in - wj * fj - dj * pd * yd) / jj
        f_in = wj * fj
    jl, djl = node_inertia(P, T, nm + 1, c, kc, tc, hc, ih)  # the load
    kin += 0.5 * djl * qd * qd
    qdd = (f_in + m_load - djl * pd * qd) / jl
    jw0, djw0 = 0.0, 0.0
    if c != 0.0:
        jw0, djw0 = interp(T, int(P[ROW_JW0]), kc, tc, hc, ih)
    pdd = ((1.0 - c) * nts - 0.5 * (djd - c * djw0) * pd * pd + kin - w0 * f0 + pot) / (jd - c * jw0)
    return pdd, qdd


__all__ = ["B_EPS", "blend", "chain_accelerations", "contact", "inertia_beyond_motor", "loss_coefficient", "lossy", "speed_sign",
           "node_inertia", "segment_force"]
