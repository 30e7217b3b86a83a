"""RK4 steps split at the switches of the full chain's intermediate nodes' friction.

An intermediate node carrying a stage's friction (``NODE_FRIC``, :mod:`.node_friction`)
switches where it reverses its speed and where, stuck, the moment on it reaches its breakaway
level, as the motor side and the load do (:mod:`.split_step`, whose RK4 trial steps this
module calls). The fixed-step loop (:func:`.integrators._rk4`) hands a step to
:func:`.switch_loop.switched_step` when :func:`node_flags` sees a node carrying friction leave
its direction within the step (at its end, at one of RK4's stages, or along the first stage's
slope) or leave rest; :func:`node_first_switch` finds the node's switch instant tau within the
step and integrates RK4 to it:

- a reversal: tau is the zero of the node's speed along the motion continued past it (its
  sliding friction held at its direction before the zero: the node's ``NF_DIR`` in a scratch
  copy of the parameters), by the Illinois method on RK4 trial steps from the step's start;
  the node restarts at rest exactly at tau, where its stick law decides;
- a breakaway: tau is where the moment on the node held at rest (its breakaway level out of
  reach) reaches its breakaway level, the moment read with the level at 0.

A node leaving rest at tau does so with the speed :data:`~.split_step.SEED` in the moment's
direction, its friction held at that direction for the rest of the step, so the rest of the
step integrates its sliding law from 0+ (the breakaway's instant is the first past the level,
so the moment there drives the node the way it leaves). The bracket is closed
to :data:`~.split_step.TAU_TOL` of the step, so the smooth stretches between switches keep
RK4's fourth order. The rest of the step is checked and split again like the motor side's
and the load's (:mod:`.switch_loop`: every switch within a step at any node, the earliest of
several flagged ones first). Compiled once, called at switches only, with the right-hand side
:func:`.kernel.rhs_phys_serial` (no inlined copy).
"""

from __future__ import annotations

from .kernel import jit, rhs_phys_serial
from .layout import NF_DIR, NF_STRIDE, NF_TS, NMID, NODE_FRIC, OFF_NODE
from .split_step import HELD, MAX_ITER, SEED, _trial, illinois_next, illinois_trial
from .vmath import inline

#: the intermediate nodes whose switches are located within a step (bits of an int64)
MAX_FLAGGED = 62


@inline
def node_flag(x, k1, k2, k3, k4, sixth, P, j):
    """Whether intermediate node j (0 the first) carrying friction may switch within the step
    whose stages' slopes are k1..k4 (x[7:] still at the step's start): its speed leaves its
    direction at the step's end, at a stage or along the first stage's slope, or leaves
    rest."""
    if P[int(P[NODE_FRIC]) + NF_STRIDE * j + NF_TS] <= 0.0:
        return False
    i = int(P[OFF_NODE]) + 2 * j + 1
    h = 6.0 * sixth
    v0 = x[i]
    v1 = v0 + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    if v0 == 0.0:
        return v1 != 0.0
    return (v1 * v0 <= 0.0 or (v0 + h * k1[i]) * v0 < 0.0 or (v0 + 0.5 * h * k2[i]) * v0 < 0.0
            or (v0 + h * k3[i]) * v0 < 0.0)


@inline
def node_flags(x, k1, k2, k3, k4, sixth, P):
    """The intermediate nodes that may switch within the step (:func:`node_flag`) as bits
    (bit j: node j; the first :data:`MAX_FLAGGED` nodes), 0 for none or without friction at
    intermediate nodes."""
    mask = 0
    if P[NODE_FRIC] > 0.0:
        for j in range(min(int(P[NMID]), MAX_FLAGGED)):
            if node_flag(x, k1, k2, k3, k4, sixth, P, j):
                mask |= 1 << j
    return mask


@jit
def _node_g(tau, t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, x0, xs, k1, k2, k3, k4, i, breakaway, cap):
    """The switch function at tau: the node's speed after a trial step of length tau with W
    (a reversal), or |its held moment| - cap after a trial step with the node held (W = H; a
    breakaway: the moment as an acceleration, read with Z)."""
    r = _trial(t, tau, p, pd, q, qd, cur, xi, s, W, T, iref, True, x, x0, xs, k1, k2, k3, k4)
    if not breakaway:
        return x[i]
    rhs_phys_serial(t + tau, r[0], r[1], r[2], r[3], r[4], r[5], s, Z, T, iref, x, k1)
    return abs(k1[i]) - cap


@jit
def _node_illinois(a, b, ga, gb, t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, x0, xs, k1, k2, k3, k4, i,
                   breakaway, cap):
    """The zero of :func:`_node_g` on [a, b] (ga gb < 0) by the Illinois method: the first
    instant past it (a breakaway: the moment beyond the level, so the node leaves rest in its
    direction; a reversal: just past the speed's zero)."""
    side = 0
    for _ in range(MAX_ITER):
        closed, c = illinois_trial(a, b, ga, gb)
        if closed:
            break
        gc = _node_g(c, t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, x0, xs, k1, k2, k3, k4, i, breakaway, cap)
        if gc == 0.0:
            return c
        a, b, ga, gb, side = illinois_next(a, b, ga, gb, c, gc, side)
    return b  # a breakaway: the first instant beyond the level; a reversal: just past the zero


@jit  # called at an intermediate node's switch only
def node_first_switch(t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, x, xs, k1, k2, k3, k4, x0, PW, j):
    """The switch of intermediate node j within the step from t (module doc): ``(True, p, pd,
    q, qd, cur, xi, tau, held)`` the state at t + tau just after it (RK4 to tau, the node at
    rest there or leaving it, x[7:] advanced to t + tau; ``held``: it leaves rest, and the
    rest of the step takes the parameters ``PW[0]``, its friction held in that direction),
    else ``(False, ...)`` with the step's result (the continued motion, or the node held all
    through), tau = dt. ``x0`` (the size of x) and ``PW`` (2 rows the size of P) are scratch."""
    for m in range(x.size):
        x0[m] = x[m]
    slot = int(P[NODE_FRIC]) + NF_STRIDE * j
    i = int(P[OFF_NODE]) + 2 * j + 1
    v0 = x0[i]
    breakaway = v0 == 0.0
    # a reversal: the node's friction held at its direction (W); a breakaway: the node held (W),
    # the moment on the node read with its level at 0 (Z)
    W, Z = PW[0], PW[1]
    for m in range(P.size):
        W[m] = Z[m] = P[m]
    tau, cap, a1 = 0.0, 0.0, 0.0
    if not breakaway:
        W[slot + NF_DIR] = 1.0 if v0 > 0.0 else -1.0
        r = _trial(t, dt, p, pd, q, qd, cur, xi, s, W, T, iref, True, x, x0, xs, k1, k2, k3, k4)
        if x[i] * v0 >= 0.0:  # the continued motion does not reverse within the step: it is the step
            return False, r[0], r[1], r[2], r[3], r[4], r[5], dt, False
        tau = _node_illinois(0.0, dt, v0, x[i], t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, x0, xs,
                             k1, k2, k3, k4, i, False, 0.0)
    else:
        W[slot + NF_TS] = HELD
        Z[slot + NF_TS] = 0.0
        r = _trial(t, dt, p, pd, q, qd, cur, xi, s, W, T, iref, True, x, x0, xs, k1, k2, k3, k4)
        rhs_phys_serial(t + dt, r[0], r[1], r[2], r[3], r[4], r[5], s, Z, T, iref, x, k1)
        a1 = k1[i]
        rhs_phys_serial(t + dt, r[0], r[1], r[2], r[3], r[4], r[5], s, P, T, iref, x, k1)
        broken = k1[i]
        if broken == 0.0:  # held at the step's end: at rest all through it
            return False, r[0], r[1], r[2], r[3], r[4], r[5], dt, False
        cap = abs(a1 - broken)  # the breakaway level as an acceleration
        g0 = _node_g(0.0, t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, x0, xs, k1, k2, k3, k4, i, True, cap)
        if g0 < 0.0:
            tau = _node_illinois(0.0, dt, g0, abs(a1) - cap, t, p, pd, q, qd, cur, xi, s, W, Z, T, iref, x, x0,
                                 xs, k1, k2, k3, k4, i, True, cap)
    # RK4 to tau (the continued motion, or held at rest), the node at rest there
    r = _trial(t, tau, p, pd, q, qd, cur, xi, s, W, T, iref, True, x, x0, xs, k1, k2, k3, k4)
    p, pd, q, qd, cur, xi = r
    x[i] = 0.0
    if breakaway:
        slide = a1
    else:  # at rest at the reversal: stuck, or breaking away the other way at once
        rhs_phys_serial(t + tau, p, pd, q, qd, cur, xi, s, P, T, iref, x, k1)
        slide = k1[i]
    if slide == 0.0:  # stuck
        return True, p, pd, q, qd, cur, xi, tau, False
    # breaking away: the node leaves rest sliding (SEED in the moment's direction, its friction held
    # at that direction for the rest of the step), so every stage sees the sliding law from 0+
    for m in range(P.size):
        W[m] = P[m]
    W[slot + NF_DIR] = 1.0 if slide > 0.0 else -1.0
    x[i] = SEED if slide > 0.0 else -SEED
    return True, p, pd, q, qd, cur, xi, tau, True


__all__ = ["MAX_FLAGGED", "node_first_switch", "node_flag", "node_flags"]
