"""Friction that holds in the reference solver: the nodes carrying it and their modes between
events.

The motor side and the load are watched as they always were: a sliding node's speed reaching
0 (restart at rest), a resting node's speed leaving a band of 1e-9 (then its reversal is
watched). While one slides its friction's sign is held in its direction (``DIR_M``,
``DIR_L``), at rest it is left to the speed. Left to the speed while sliding, a node that
comes to stick (its applied moment within the Coulomb level) has no motion past its zero:
beyond it the friction pushes it back, so no implicit step ending there converges and LSODA
crept towards the zero until its budget was spent; whether one of its steps happened to land
past the zero depended on the first steps after the restarts, hence on the run's duration
(the two-switch chain's motor, sticking at 0.0229 s of a 0.35 s run, 0.0070 s of a 0.5 s one,
met in time in a 1 s one). Held, the friction is smooth across the zero and the reversal's
event is met in every run. The full chain's intermediate nodes are
solved in modes: between two events each is in one mode, sliding in a held direction (its
friction's sign held there, its ``NF_DIR`` in the solver's copy of the parameters, so that
the right-hand side is smooth
across the speed's zero and the solver's Jacobian never sees the friction's jump), or stuck
at rest (exactly zero speed and acceleration by the stick law). The events end a mode: a
sliding node's speed reaching 0 against its direction (the reversal: the solve restarts with
the node at rest, where the stick law decides between stick and breaking away), a stuck
node's acceleration leaving 0 (the breakaway's instant: the solve restarts with the node at
rest, sliding in the direction of the moment on it, read with its breakaway level at 0).
Restarting at the breakaway matters for a stiff solver: a Jacobian taken while the node
sticks carries the friction's jump as a huge stiffness and, reused past the breakaway,
would hold the node near rest long after it breaks away (the band's watch let LSODA hold an
intermediate node for over a millisecond; on the motor side and the load it keeps the
reference of the existing checks, whose LSODA error near a breakaway is about 1e-11 rad).

Right after a breakaway a node leaves rest tangentially: its moment has just reached the
breakaway level, which the sliding friction at 0+ equals, so its speed grows as the square
of the time and lies within the solver's error for a while. A reversal watched at exactly 0
there fires on that error (Radau at rtol = atol = 1e-12 stuck and broke the wheel away
10,000 times at one instant), so until the next event the node that broke away is watched
for a reversal beyond the band of the motor side's and the load's watch (1e-9 of the largest
speed; the node restarts at rest either way). The motor side and the load keep the watch at
0: they leave rest with a seed of speed (:data:`~.layout.SEED`) whose sign their friction
takes at once.

An intermediate node that enters a sliding mode at rest (at its breakaway, or sliding on at
once after a reversal) leaves rest with the same seed in its held direction. At exactly 0 the
right-hand side reads the stick law, which differs from the held sliding law by what the
breakaway's event leaves of the moment below the level: its root finder returns the stuck side
(the event is -1e-300 there, the smaller magnitude brentq keeps), 1e-11 rad/s^2 short at the
wheel. An implicit solver's finite-difference Jacobian steps a zero speed by sqrt(eps) atol (1.5e-20
at atol = 1e-12) and read that jump as a stiffness of +7e8 1/s; Radau's simplified Newton
iteration converged on it to a wrong step and its error estimate, solved with the same matrix,
accepted it: its first step after the wheel's breakaway ran 38 us with the wheel moving the
wrong way (+1.5e-9 rad/s instead of -9.9e-6), met the reversal's band and restarted the
wheel, 1.6e-7 of the swing off LSODA from there on (scipy 1.16 and 1.17 alike). Seeded, the
node reads the sliding law its mode holds at every trial state, and Radau agrees with LSODA to
3.0e-11 of the swing, BDF to 3.5e-11.

Until their breakaway's event the motor side and the load at rest are held there: the
solver's function reads their speed as 0 (``fun.rest``, :func:`~.ivp.make_fun`) whatever its
trial states hold. Read as they came, an implicit solver's Newton iterate whose speed rounds
off 0 the wrong way (-1e-38) past the breakaway met the sliding friction against the
moment, a jump of twice the breakaway level, and no step across the breakaway converged
(Radau and BDF at rtol = atol = 1e-12 failed at the two-switch chain's first breakaway, t =
0.00398 s: "Required step size is less than spacing between numbers"). Held, the right-hand
side is continuous across the breakaway (the moment beyond the level grows from 0) and the
step ending past it meets the breakaway's event. The intermediate nodes' stuck mode reads
the stick law as it comes (held the same way, Radau's events on its lower-order dense
output placed the wheel's breakaway worse: 5.6e-8 of the swing against 5.3e-9, both measured
before the seed above).
"""

from __future__ import annotations

import numpy as np

from . import layout as lo
from .kernel import rhs
from .layout import SEED


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


def _terminal(event, node, direction, reversal=False, breakaway=False):
    """``event`` marked as a terminal solve_ivp event of the node whose speed is x[node],
    crossing 0 in ``direction``, with what it ends: a sliding node's ``reversal``, a resting
    node's ``breakaway`` (neither: the motor side or the load leaving its band).
    :meth:`FrictionModes.restart` reads the markers of the motor side and the load; an
    intermediate node's mode at the event is its held direction."""
    event.terminal = True
    event.direction = direction
    event.node = node
    event.reversal = reversal
    event.breakaway = breakaway
    return event


def breakaway_gauge(model, P, iref_box):
    """``g(t, y, i, side=False)``: the breakaway distance of node i (x's index of its speed)
    held at rest at (t, y), over its inertia, from the right-hand side with ``HOLD_GAUGE`` set
    (:func:`servo_toolkit.sim.kernel.gear_at_rest`: > 0 beyond its band, the band the right-hand
    side holds the node in; with ``side``, > 0 where it would break away forward)."""
    Z = {False: P.copy(), True: P.copy()}
    Z[False][lo.HOLD_GAUGE], Z[True][lo.HOLD_GAUGE] = 1.0, 2.0
    aux = np.empty(lo.NAUX)
    d = np.empty(model.nx)

    def gauge(t, y, i, side=False):
        x = np.array(y, dtype=float)
        x[i] = 0.0
        if model.rigid:
            x[3] = 0.0
        rhs(t, x, Z[side], model.T, iref_box[0], d, aux)
        return float(d[i])

    return gauge


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
    gauge : callable, optional
        :func:`breakaway_gauge`: the motor side's and the load's breakaway distance at rest
        (the band a lossy gear holds in), whose zero ends their rest.
    """

    def __init__(self, model, P, fun, make, gauge=None):
        self.model, self.P, self.fun, self.make, self.gauge = model, P, fun, make, gauge
        self.nodes = friction_nodes(model, P)
        self.slots = {i: _slots(model, P, i) for i in self.nodes}
        self.dirs = dict.fromkeys(self.nodes, 0.0)
        self.rest = {}  # a stuck node's position (and a rigid model's output) where it stuck
        self.fresh = None  # the node that broke away at the last restart (its reversal is banded)

    def _hold(self, i):
        for s in self.slots[i][0]:
            self.P[s] = self.dirs[i]

    def start(self, x) -> None:
        """A controller sample's solve begins at x: the band of the motor side's and the load's
        breakaway watch (1e-9 of the largest speed, at least 1e-9)."""
        self.scale = 1e-9 * max(1.0, float(np.max(np.abs(x[self.nodes]))))

    def _leave_rest(self, t, x, only=None) -> None:
        """Seed the motor side or the load at rest (or ``only``) that is beyond its band at
        (t, x): its speed :data:`~.layout.SEED` towards the side it breaks away to, so
        that the solve integrates the sliding law from 0+ (as the fixed-step split step does)."""
        for i in [n for n in self.nodes if n <= 3] if only is None else [only]:
            if x[i] == 0.0 and (only is not None or self.gauge(t, x, i) > 0.0):
                x[i] = SEED if self.gauge(t, x, i, side=True) > 0.0 else -SEED
                if self.model.rigid:
                    x[3] = x[1]

    def _breakaway(self, i):
        """A resting motor side's or load's breakaway distance crossing 0 (:func:`breakaway_gauge`)."""
        def br(t, y, i=i):
            return self.gauge(t, y, i)
        return _terminal(br, i, 1.0, breakaway=True)

    def _watch(self, i, x):
        """The motor side's and the load's event (their speed reaching 0 from its side, or,
        at rest, leaving a band of ``scale`` as a safeguard beside their breakaway's event);
        while sliding their friction's sign is held (:meth:`events`)."""
        if x[i] != 0.0:
            return self._reversal(i, 1.0 if x[i] > 0 else -1.0)

        def ev(t, y, i=i):
            return abs(y[i]) - self.scale
        return _terminal(ev, i, 1.0)

    def _reversal(self, i, direction):
        """Node i, sliding in ``direction``, reversing: its speed reaching 0 against it, or,
        for the node that has just broken away, passing the band of :attr:`scale` against it
        (module docstring)."""
        band = self.scale * direction if i == self.fresh else 0.0

        def ev(t, y, i=i):
            return y[i] + band
        return _terminal(ev, i, -direction, reversal=True)

    def events(self, t0, x) -> list:
        """Each node's mode at (t0, x), its direction set in P, and the terminal events that
        end the modes (each with ``node``). The motor side and the load (x[1], x[3]) keep
        their own watch (:meth:`_watch`), their friction held in the direction of their speed
        while they slide (left to the speed at rest); the modes are the intermediate nodes'.
        x changes in place: a node entering a sliding mode at rest takes the speed
        :data:`~.layout.SEED` in its direction (module doc), a resting motor side or load
        beyond its band likewise (:meth:`_leave_rest`)."""
        for i in self.nodes:  # sliding nodes first: the moments on the resting ones depend on them
            if i <= 3:
                continue
            if x[i] != 0.0:
                self.dirs[i] = 1.0 if x[i] > 0.0 else -1.0
            self._hold(i)
        d0 = None
        for i in self.nodes:
            if i <= 3:
                continue
            if x[i] == 0.0 and self.dirs[i] == 0.0:
                d0 = self.fun(t0, x) if d0 is None else d0
                self.dirs[i] = float(np.sign(d0[i]))  # 0: stuck
                self._hold(i)
                if self.dirs[i] == 0.0:
                    self.rest[i] = (x[i - 1], x[2])
        for i in self.nodes:  # a sliding mode entered at rest: the seed, so the sliding law is read
            if i > 3 and x[i] == 0.0 and self.dirs[i] != 0.0:
                x[i] = SEED * self.dirs[i]
        if self.gauge is not None:
            self._leave_rest(t0, x)
        for i in self.nodes:  # the motor side and the load: sliding in a held direction, or at rest
            if i <= 3:
                self.dirs[i] = 0.0 if x[i] == 0.0 else (1.0 if x[i] > 0.0 else -1.0)
                self._hold(i)
        # the motor side and the load at rest are held there until their breakaway's event: the
        # solver's trial states, whose speed there may be off 0 by its rounding, are read at
        # rest (module doc)
        rest = [i for i in self.nodes if i <= 3 and x[i] == 0.0]
        if self.model.rigid and 1 in rest:
            rest.append(3)
        self.fun.rest = rest
        events = []
        for i in self.nodes:
            if i <= 3:
                if x[i] == 0.0 and self.gauge is not None:
                    events.append(self._breakaway(i))
                events.append(self._watch(i, x))
                continue
            if self.dirs[i] != 0.0:  # sliding: its speed reaching 0 against its direction
                events.append(self._reversal(i, self.dirs[i]))
            else:  # stuck: its acceleration leaving 0
                def ev(t, y, i=i):  # read at rest (an interpolant may not hold the speed at 0)
                    y = np.array(y, dtype=float)
                    y[i] = 0.0
                    return abs(self.fun(t, y)[i]) - 1e-300
                events.append(_terminal(ev, i, 1.0, breakaway=True))
        return events

    def restart(self, ev, t, x) -> None:
        """The state after the event ``ev`` at t (x changed in place): the node at rest; after
        a reversal its mode is decided at the restart, after a breakaway it slides in the
        direction of the moment on it (its seed of speed set by :meth:`events`)."""
        i = ev.node
        self.fresh = i if ev.breakaway and i > 3 else None  # a held direction: not the motor side's or the load's
        if i <= 3 and ev.breakaway:  # leaves rest here, towards the side beyond its band
            x[i] = 0.0
            self._leave_rest(t, x, only=i)
            return
        if i <= 3 and not ev.reversal:  # the motor side or the load left its band: watch its reversal
            return
        x[i] = 0.0
        rigid = i == 1 and self.model.rigid
        if rigid:
            x[3] = 0.0  # a rigid model's output speed is the motor side's
        if i <= 3 or self.dirs[i] != 0.0:  # a reversal
            self.dirs[i] = 0.0
            return
        # a breakaway: the node has not moved since it stuck (the event's state is the solver's
        # interpolant, which a step across the breakaway bends)
        x[i - 1] = self.rest[i][0]
        if rigid:
            x[2] = self.rest[i][1]
        Z = self.P.copy()
        Z[self.slots[i][1]] = 0.0
        self.dirs[i] = float(np.sign(self.make(Z)(t, x)[i])) or 1.0


__all__ = ["FrictionModes", "breakaway_gauge", "friction_nodes"]
