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


__all__ = ["slip_friction", "stuck_or_breaking"]
