"""Friction that holds in the reference solver: the nodes carrying it and their modes between
events.

Between two events each node carrying friction that holds is in one mode: sliding in a held
direction (its friction's sign held there, ``DIR_M``, ``DIR_L`` or the intermediate node's
``NF_DIR`` in the solver's copy of the parameters, so that the right-hand side is smooth
across the speed's zero and the solver's Jacobian never sees the friction's jump), or stuck
at rest (exactly zero speed and acceleration by the stick law). The events end a mode: a
sliding node's speed reaching 0 against its direction (the reversal: the solve restarts with
the node at rest, where the stick law decides between stick and breaking away), a stuck
node's acceleration leaving 0 (the breakaway's instant: the solve restarts with the node at
rest, sliding in the direction of the moment on it, read with its breakaway level at 0).
Restarting at the breakaway matters for a stiff solver: a Jacobian taken while the node
sticks carries the friction's jump as a huge stiffness and, reused past the breakaway,
would hold the node near rest long after it breaks away.
"""

from __future__ import annotations

import numpy as np

from . import layout as lo


def friction_nodes(model, P) -> list:
    """Indices in x of the speeds of the nodes carrying friction that holds: the motor side,
    the load, the full chain's intermediate nodes with friction of their own."""
    if P[lo.STICK] <= 0.0:
        return []
    nodes = []
    if P[lo.TS_M] > 0.0 or (model.rigid and P[lo.TS_L] > 0.0):
        nodes.append(1)
    if not model.rigid and P[lo.TS_L] > 0.0:
        nodes.append(3)
    f, first = int(P[lo.NODE_FRIC]), int(P[lo.OFF_NODE])
    if f > 0:
        nodes += [first + 2 * j + 1 for j in range(int(P[lo.NMID])) if P[f + lo.NF_STRIDE * j + lo.NF_TS] > 0.0]
    return nodes


def _slots(model, P, i):
    """The direction slots and the breakaway slots in P of the node whose speed is x[i]."""
    if i == 1:
        return ([lo.DIR_M, lo.DIR_L], [lo.TS_M, lo.TS_L]) if model.rigid else ([lo.DIR_M], [lo.TS_M])
    if i == 3:
        return [lo.DIR_L], [lo.TS_L]
    b = int(P[lo.NODE_FRIC]) + lo.NF_STRIDE * ((i - int(P[lo.OFF_NODE]) - 1) // 2)
    return [b + lo.NF_DIR], [b + lo.NF_TS]


class FrictionModes:
    """The modes of the nodes carrying friction along one reference solve (module doc).

    Parameters
    ----------
    model : Model
    P : numpy.ndarray
        The solver's own copy of the parameters, read by ``fun``: its direction slots are
        set here.
    fun : callable
        ``f(t, x)`` on ``P`` (:func:`servo_toolkit.sim.ivp.make_fun`).
    make : callable
        ``make(P)``: such a function on other parameters (the moment read with a node's
        breakaway level at 0).
    """

    def __init__(self, model, P, fun, make):
        self.model, self.P, self.fun, self.make = model, P, fun, make
        self.nodes = friction_nodes(model, P)
        self.slots = {i: _slots(model, P, i) for i in self.nodes}
        self.dirs = dict.fromkeys(self.nodes, 0.0)

    def _hold(self, i):
        for s in self.slots[i][0]:
            self.P[s] = self.dirs[i]

    def events(self, t0, x) -> list:
        """Each node's mode at (t0, x), its direction set in P, and the terminal events that
        end the modes (each with ``node``)."""
        for i in self.nodes:  # sliding nodes first: the moments on the resting ones depend on them
            if x[i] != 0.0:
                self.dirs[i] = 1.0 if x[i] > 0.0 else -1.0
            self._hold(i)
        d0 = None
        for i in self.nodes:
            if x[i] == 0.0 and self.dirs[i] == 0.0:
                d0 = self.fun(t0, x) if d0 is None else d0
                self.dirs[i] = float(np.sign(d0[i]))  # 0: stuck
                self._hold(i)
        events = []
        for i in self.nodes:
            if self.dirs[i] != 0.0:
                def ev(t, y, i=i):
                    return y[i]
                ev.direction = -self.dirs[i]
            else:
                def ev(t, y, i=i):  # read at rest (an interpolant may not hold the speed at 0)
                    y = np.array(y, dtype=float)
                    y[i] = 0.0
                    return abs(self.fun(t, y)[i]) - 1e-300
                ev.direction = 1.0
            ev.terminal = True
            ev.node = i
            events.append(ev)
        return events

    def restart(self, ev, t, x) -> None:
        """The state after the event ``ev`` at t (x changed in place): the node at rest; after
        a reversal its mode is decided at the restart, after a breakaway it slides in the
        direction of the moment on it."""
        i = ev.node
        x[i] = 0.0
        if i == 1 and self.model.rigid:
            x[3] = 0.0  # a rigid model's output speed is the motor side's
        if self.dirs[i] != 0.0:  # a reversal
            self.dirs[i] = 0.0
            return
        Z = self.P.copy()
        Z[self.slots[i][1]] = 0.0
        self.dirs[i] = float(np.sign(self.make(Z)(t, x)[i])) or 1.0


__all__ = ["FrictionModes", "friction_nodes"]
