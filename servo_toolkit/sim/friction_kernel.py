"""Friction that holds, inside the compiled kernels (Karnopp-type stick at zero speed).

A node carrying friction (the motor shaft, the load) slides with the Stribeck law

    F(v) = (Tc + (Ts - Tc) exp(-(v / v_st)^2)) sign(v)           (v != 0)

and, at exactly zero speed, sticks: its acceleration is 0 while the applied moment (every
other moment on the node) stays within the breakaway level Ts; beyond it the node breaks
away against Ts (the Stribeck curve's value at v = 0+). A node stuck at v = 0 keeps its
position exactly (RK4's stages all see v = 0 and zero acceleration). The integrators locate a
node's speed reversal within the step and restart it at v = 0 exactly
(:mod:`servo_toolkit.sim.integrators`), so the stick test is met where the physics meets it;
the reference solver stops on the same reversal as an event (:mod:`servo_toolkit.sim.ivp`).
"""

from __future__ import annotations

from ..core.jit_cache import install as _install_cache

_install_cache()  # noqa: E402 - before any kernel below is decorated

from .layout import (NF_DIR, NF_INV_VS, NF_STRIDE, NF_TC, NF_TS, NF_VISC, NMID, NODE_FRIC,  # noqa: E402
                     NX_PHYS, OFF_NODE, STICK)
from .vmath import TANH_ONE, exp_neg, inline  # noqa: E402


@inline
def slip_friction(v, tc, ts, inv_vs, direction):
    """Sliding friction at speed v != 0, signed with v (or with ``direction`` when it is not
    0: the friction of a motion continued past its speed's zero, which the switch location of
    :mod:`.split_step` integrates): Tc + (Ts - Tc) exp(-(v / v_st)^2).

    The exponential is :func:`~.vmath.exp_neg`'s (no library call, so the batched lanes
    vectorize it; within 1 ulp), taken as 0 beyond (v / v_st)^2 = 44 (exp(-44) = 8e-20)."""
    y = v * inv_vs
    y2 = y * y
    stribeck = 0.0 if y2 >= 2.0 * TANH_ONE else exp_neg(y2)
    mag = tc + (ts - tc) * stribeck
    ahead = v > 0.0 if direction == 0.0 else direction > 0.0
    return mag if ahead else -mag


@inline
def stuck_or_breaking(applied, cap):
    """The net moment on a node at rest: 0 while |applied| <= cap (it sticks), else the
    applied moment less the breakaway level cap against it."""
    if applied > cap:
        return applied - cap
    if applied < -cap:
        return applied + cap
    return 0.0


@inline
def node_moment(P, j, v, applied):
    """The net moment on the full chain's intermediate node j (1..NMID) moving at v, from the
    ``applied`` moment (every other moment on it: the segments on either side, the velocity
    terms), with the node's own friction (``NODE_FRIC``; none when 0): its viscous part, and
    with friction that holds (``STICK``) its sliding law (:func:`slip_friction`) or, at
    exactly v = 0, the stick law (:func:`stuck_or_breaking`) against its breakaway level. The
    chain's mass matrix is diagonal in the node coordinates, so the decision is the node's
    alone."""
    o = int(P[NODE_FRIC])
    if o == 0:
        return applied
    b = o + NF_STRIDE * (j - 1)
    applied -= P[b + NF_VISC] * v
    ts = P[b + NF_TS]
    if ts > 0.0 and P[STICK] > 0.0:
        if v == 0.0:
            return stuck_or_breaking(applied, ts)
        return applied - slip_friction(v, P[b + NF_TC], ts, P[b + NF_INV_VS], P[b + NF_DIR])
    return applied


@inline
def advance_moving_states(x, k1, k2, k3, k4, sixth, P, lands):
    """RK4's update of the states in x[NX_PHYS:] that move between samples (a continuous
    controller's, the full chain's nodes). With ``lands`` (friction that holds at an
    intermediate node, ``NODE_FRIC``) a node carrying it whose speed leaves its direction
    within the step ends the step at rest, where its stick law decides between stick and
    slip (the Karnopp landing of the cam paper's scheme; the reversal is not located within
    the step, so the step across it is of first order). Leaving its direction: at the step's
    end, or at any of RK4's stages, or along the first stage's slope (the later stages
    straddle the friction's jump and may push the speed back: a result on the same side can
    hide the reversal)."""
    o = int(P[NODE_FRIC]) if lands else 0
    first = int(P[OFF_NODE])
    nm = int(P[NMID])
    for j in range(NX_PHYS, x.size):
        v0 = x[j]
        x[j] = v0 + sixth * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        if o > 0 and v0 != 0.0:
            m = j - first
            if m >= 0 and m < 2 * nm and m % 2 == 1 and P[o + NF_STRIDE * (m // 2) + NF_TS] > 0.0:
                h = 6.0 * sixth
                if (x[j] * v0 <= 0.0 or (v0 + h * k1[j]) * v0 < 0.0 or (v0 + 0.5 * h * k2[j]) * v0 < 0.0
                        or (v0 + h * k3[j]) * v0 < 0.0):
                    x[j] = 0.0


__all__ = ["advance_moving_states", "node_moment", "slip_friction", "stuck_or_breaking"]
