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

from .layout import NF_DIR, NF_INV_VS, NF_STRIDE, NF_TC, NF_TS, NF_VISC, NODE_FRIC, STICK  # noqa: E402
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


__all__ = ["node_moment", "slip_friction", "stuck_or_breaking"]
