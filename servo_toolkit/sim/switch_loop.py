"""The RK4 step split at every friction switch located within it, at any node carrying
friction that holds: the motor side and the load (:func:`.split_step.first_switch`) and the
full chain's intermediate nodes (:func:`.node_switch.node_first_switch`).

The fixed-step loops (:func:`.integrators._rk4`, the Monte Carlo lanes) hand a step to
:func:`switched_step` when their test sees a node switch within it (``ends``: the motor side
or the load, :func:`.split_step.switch_ahead` or a stage that left a direction; ``mask``: the
intermediate nodes, :func:`.node_switch.node_flags`). The step integrates RK4 to the earliest
of the flagged nodes' switches (each located along its own continued or held motion; with
more than one flagged, each is located and the earliest kept), and takes the rest of the step
as a step of its own, checked by the same tests (:func:`.split_step.rk4_checked` for the
motor side and the load, :func:`.node_switch.node_flags` on its stages' slopes) and split
again where a switch falls within it, up to :data:`.split_step.MAX_SWITCHES` switches, after
which the rest is one plain RK4 step. So two switches within one step, at any two nodes, keep
RK4's fourth order on the smooth stretches between them.
"""

from __future__ import annotations

from .kernel import jit
from .node_switch import node_first_switch, node_flags
from .split_step import MAX_SWITCHES, first_switch, rk4_checked


@jit
def _locate(c, t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x, xs, k1, k2, k3, k4, pd_new, qd_new,
            x0, PW):
    """The switch of candidate c within the step: c < 0 the motor side or the load, else the
    intermediate node c. Returns ``(split, p, pd, q, qd, cur, xi, tau, held)``."""
    if c < 0:
        r = first_switch(t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x, xs, k1, k2, k3, k4,
                         pd_new, qd_new, x0, PW)
        return r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], False
    return node_first_switch(t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, x, xs, k1, k2, k3, k4, x0, PW, c)


@jit
def _earliest(t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x, xs, k1, k2, k3, k4, pd_new, qd_new,
              x0, PW, ends, mask):
    """The earliest switch among the candidates (``ends``, ``mask``: :func:`switched_step`),
    as :func:`_locate` returns it; with none splitting, the first candidate's step. x[7:] at
    the step's start is kept in ``PW[3]`` while more than one is located."""
    first, count = -2, 0
    if ends:
        first, count = -1, 1
    m, j = mask, 0
    while m:
        if m & 1:
            if first == -2:
                first = j
            count += 1
        m >>= 1
        j += 1
    if count == 1:
        return _locate(first, t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x, xs, k1, k2, k3, k4,
                       pd_new, qd_new, x0, PW)
    start = PW[3]
    for n in range(x.size):
        start[n] = x[n]
    best, best_tau, last = first, 2.0 * dt, -2
    c = -1 if ends else 0
    while c < 0 or (mask >> c) != 0:
        if c < 0 or (mask >> c) & 1:
            for n in range(x.size):
                x[n] = start[n]
            r = _locate(c, t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x, xs, k1, k2, k3, k4,
                        pd_new, qd_new, x0, PW)
            last = c
            if r[0] and r[7] < best_tau:
                best, best_tau = c, r[7]
        c += 1
    if best == last:
        return r
    for n in range(x.size):
        x[n] = start[n]
    return _locate(best, t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x, xs, k1, k2, k3, k4,
                   pd_new, qd_new, x0, PW)


@jit  # called at a switch only
def switched_step(t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x, xs, k1, k2, k3, k4, pd_new, qd_new,
                  x0, PW, ends, mask):
    """The step from t of nodes that may switch within it, split at the switches located
    within it (module doc). ``ends``: the motor side or the load may switch (``pd_new``,
    ``qd_new``: their speeds at the plain step's end); ``mask``: the intermediate nodes that
    may (bits, :func:`.node_switch.node_flags`), k1..k4 holding the plain step's slopes.
    Returns the step's new ``(p, pd, q, qd, cur, xi)`` (x[7:] advanced in place when they
    move). ``x0`` (the size of x) and ``PW`` (4 rows, each at least the size of P and of x) are
    scratch: the step allocates nothing."""
    n = 0
    while True:
        split, p, pd, q, qd, cur, xi, tau, held = _earliest(t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont,
                                                            rigid, x, xs, k1, k2, k3, k4, pd_new, qd_new, x0, PW,
                                                            ends, mask)
        if not split:
            return p, pd, q, qd, cur, xi
        n += 1
        t += tau
        dt -= tau
        for j in range(x.size):  # x[7:] at the switch, should the rest be split again
            x0[j] = x[j]
        # the rest of the step: with the parameters the switch left (an intermediate node
        # leaving rest: its friction held in the direction it leaves to)
        W = PW[0] if held else P
        p1, pd1, q1, qd1, cur1, xi1, ends = rk4_checked(t, dt, p, pd, q, qd, cur, xi, s, W, T, iref, cont, rigid,
                                                        x, xs, k1, k2, k3, k4)
        mask = node_flags(x0, k1, k2, k3, k4, dt / 6.0, P)
        if not (ends or mask) or n >= MAX_SWITCHES:
            return p1, pd1, q1, qd1, cur1, xi1
        for j in range(x.size):
            x[j] = x0[j]
        pd_new, qd_new = pd1, qd1


__all__ = ["switched_step"]
