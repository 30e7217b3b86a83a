"""The drivetrain's compliances and losses inside the compiled kernels: the elasto-backlash
contact law, a compliance's force, the loss coefficient and its folding into the motor side's
equation, and the full chain's node accelerations (the equations in
:mod:`servo_toolkit.sim.kernel` and :mod:`servo_toolkit.sim.chain_model`)."""

from __future__ import annotations

from ..core.jit_cache import install as _install_cache

_install_cache()  # noqa: E402 - before any kernel below is decorated

from .layout import (BETA, ETA_HALF, ETA_MEAN, HALF_PLAY, INV_H, INV_JD0, INV_TAU_S, JW, KSCALE,  # noqa: E402
                     NMID, OFF_NODE, OFF_SEG, SEG_J, SEG_JW, SEG_LOSS, SEG_PLAY, SEG_STRIDE, T_K, T_KS,
                     TAB_H, WS)
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
def loss_coefficient(P, nts, jd, pd, n, rest):
    """The drivetrain's loss coefficient c at this state: 1 - eta driving, 1 - 1/eta_b
    back-driven (negative), blended by the smooth signs of the transmitted torque and of the
    speed (c T p' >= 0: the loss never supplies power); 0 for a lossless chain.

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
    sg = tanh(t_free * P[INV_TAU_S]) * tanh(abs(n) * pd * P[WS])
    return (P[ETA_MEAN] + P[ETA_HALF] * sg) * sg


@inline
def lossy(P, nts, jd, djd, pd, n, dn, rest):
    """The drivetrain's loss (LossyGear-like) folded into the motor side's equation
    ``jd p'' = nts - djd p'^2 / 2 + rest``: returns its ``(nts, jd, djd)`` with the loss.

    The loss acts on the torque transmitted past the members before it (rotor, pinion:
    inertia J_w = JW n^2 at the output), T = nts - J_w p'' - J_w' p'^2 / 2, which loses
    c T (:func:`loss_coefficient`). Solved for p'': nts and J_w scale by (1 - c), the rest of
    the motor side stays.
    """
    if P[ETA_MEAN] <= 0.0:
        return nts, jd, djd
    c = loss_coefficient(P, nts, jd, pd, n, rest)
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
def chain_accelerations(p, pd, q, qd, nts, jd, djd, n, dn, m_load, kc, tc, P, T, x, dx):
    """The full chain (``P[NMID]`` intermediate nodes, :mod:`servo_toolkit.sim.chain_model`):
    writes the intermediate nodes' derivatives into dx and returns ``(p'', q'')``.

    Segment s joins node s and s + 1 (node 0 = p, the last = q); its stiffness is tabulated
    at p (its variation adds -k_s'(p) z_s^2 / 2 to the motor side's equation, so the
    undamped chain conserves energy). The losses act where the chain has them, with one
    coefficient c for the whole chain (:func:`loss_coefficient`, judged at the motor side):
    node j's inertia J_j - c J_w,j and segment s's force weighted by 1 - c l_s,
    l_s = (1 - eta / Pi_s) / (1 - eta) (driving: eta / Pi_s, the chain's driving-mode form).
    """
    nm = int(P[NMID])
    o = int(P[OFF_NODE])
    g = int(P[OFF_SEG])
    hc, ih, ks, beta = P[TAB_H], P[INV_H], P[KSCALE], P[BETA]
    k0, dk0 = interp(T, T_K, kc, tc, hc, ih)
    f0, z0 = segment_force(k0 * ks, p - x[o], pd - x[o + 1], P[HALF_PLAY], beta)
    dk0 *= ks
    c = loss_coefficient(P, nts, jd, pd, n, -f0 - 0.5 * dk0 * z0 * z0)
    w = 1.0 - c * P[g + SEG_LOSS]
    pot = -0.5 * w * dk0 * z0 * z0
    f_in = w * f0
    for j in range(1, nm + 1):
        a = o + 2 * (j - 1)
        y, yd = x[a], x[a + 1]
        if j < nm:
            yn, ynd = x[a + 2], x[a + 3]
        else:
            yn, ynd = q, qd
        kj, dkj = interp(T, T_KS + 2 * (j - 1), kc, tc, hc, ih)
        gj = g + SEG_STRIDE * j
        fj, zj = segment_force(kj * ks, y - yn, yd - ynd, P[gj + SEG_PLAY], beta)
        wj = 1.0 - c * P[gj + SEG_LOSS]
        pot -= 0.5 * wj * dkj * ks * zj * zj
        gi = gj - SEG_STRIDE  # node j's inertia sits with the segment before it
        dx[a] = yd
        dx[a + 1] = (f_in - wj * fj) / (P[gi + SEG_J] - c * P[gi + SEG_JW])
        f_in = wj * fj
    jw = P[JW] * n * n
    pdd = ((1.0 - c) * nts - 0.5 * (djd - c * 2.0 * P[JW] * n * dn) * pd * pd - w * f0 + pot) / (jd - c * jw)
    gl = g + SEG_STRIDE * nm
    qdd = (f_in + m_load) / (P[gl + SEG_J] - c * P[gl + SEG_JW])
    return pdd, qdd


__all__ = ["B_EPS", "chain_accelerations", "contact", "loss_coefficient", "lossy", "segment_force"]
