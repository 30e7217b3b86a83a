"""RK4 steps split at friction's switches, located to high order within the step.

Friction that holds (:mod:`.friction_kernel`) switches where a node carrying it reverses its
speed (it stops: stick or slide on the other way) and where a stuck node breaks away (the
moment on it reaches the breakaway level). The right-hand side jumps there, so a step across
a switch is of low order; the fixed-step loops (:func:`.integrators._rk4`, the Monte Carlo
lanes) hand such a step to :func:`.switch_loop.switched_step`, whose locator for the motor
side and the load (:func:`first_switch`) finds the switch's instant tau
within the step and integrates RK4 to it and from it:

- a reversal: tau is the zero of the node's speed along the motion continued smoothly past
  it (its sliding friction held at its direction before the zero: ``DIR_M``, ``DIR_L`` in a
  scratch copy of the parameters), found by the Illinois method on RK4 trial steps from the
  step's start, each of RK4's own order on that smooth motion (the motor side and the load
  both reversing along it: the earlier of their zeros); the node restarts at rest exactly at
  tau, where the friction decides between stick and slip;
- a breakaway: tau is where the node's signed breakaway distance crosses 0, along the motion
  with the node held (its breakaway level out of reach in the scratch copy), the distance
  read by the right-hand side with ``HOLD_GAUGE`` = 1 in another
  (:func:`.friction_kernel.gear_at_rest`: for the motor side of a lossy gear, how far the
  torques on the gear are beyond its band, asymmetric with the efficiencies; for a node
  without one, |moment| less its level); the node stays at rest exactly up to tau.

A node breaking away at tau (or at a reversal whose moment exceeds the breakaway level)
leaves rest with the speed :data:`SEED` in the direction it breaks away to, so the rest of the step
integrates the sliding law from 0+ (its friction jumps from the law at rest to the sliding
one at tau, not somewhere among the stages).

The iteration stops when the bracket is within :data:`TAU_TOL` of the step, so the switch's
instant costs no more than RK4's own error; the smooth stretches between switches keep RK4's
fourth order. Where the continued motion does not switch within the step (a reversal the
first stage's slope predicted, a stage that crossed a speed's zero or broke away from its
estimate of the state, when the continued motion does not) that motion is the step.

After a switch the rest of the step, [t + tau, t + dt], is a step of its own: its plain RK4
step (:func:`rk4_checked`) is checked with the fixed-step loops' own test (:func:`switch_ahead`
from its first stage's slopes and its result, :func:`stage_turns` on its stages; the full
chain's intermediate nodes by :func:`.node_switch.node_flags`) and, where a second switch falls
within it, split again in turn, up to :data:`MAX_SWITCHES` switches per step
(:mod:`.switch_loop`, for every node carrying friction).

Everything here is compiled once as functions of their own (called at switches only), with
the right-hand side :func:`kernel.rhs_phys_serial`, never another inlined copy.
"""

from __future__ import annotations

from .kernel import inline, jit, rhs_phys_serial
from .layout import DIR_L, DIR_M, HOLD_GAUGE, NX_PHYS, TS_L, TS_M

#: the switch's instant is located to this fraction of the step (the Illinois bracket's width)
TAU_TOL = 1e-12
#: most Illinois iterations per switch (about 6 to 10 are taken)
MAX_ITER = 60
#: most switches located within one step; the rest of the step after the last is one RK4 step
MAX_SWITCHES = 4
#: a breakaway level out of reach: the node held at rest
HELD = 1e300
#: the speed (rad/s, m/s) a node breaking away leaves rest with: its direction only
SEED = 1e-290


@inline
def rk4_coefficients(stage, dt):
    """Classical RK4's stage k = 0..3: it evaluates at t + c_k from the state advanced by c_k
    times the previous stage's slopes, which enter the update with weight w_k (of dt / 6).
    Returns (c_k, w_k)."""
    c = 0.0 if stage == 0 else (dt if stage == 3 else 0.5 * dt)
    w = 2.0 if stage == 1 or stage == 2 else 1.0
    return c, w


@jit  # called at a speed reversal only: compiled once, outside the step loop
def _rk4_scalars(t, h, p, pd, q, qd, cur, xi, s, P, T, iref, cont, x, xs, k1, k2, k3, k4):
    """One classical RK4 step of length h from the physical state given as scalars (a
    continuous controller's and the full chain's states x[7:] are advanced in place).
    Returns the advanced ``(p, pd, q, qd, cur, xi)``, then the first stage's slopes of the
    node speeds and whether a later stage's speeds left a node's direction at the step's
    start (:func:`stage_turns`).

    Its right-hand side is :func:`kernel.rhs_phys_serial`, called rather than inlined: this
    step runs only where a step is split, and a call compiles in a fraction of the time of
    another inlined copy of the whole right-hand side.
    """
    nx = x.size
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    u0 = u1 = u2 = u3 = u4 = u5 = 0.0
    g1 = g3 = 0.0
    turned = False
    for stage in range(4):
        c, w = rk4_coefficients(stage, h)
        kout = k1 if stage == 0 else (k2 if stage == 1 else (k3 if stage == 2 else k4))
        if cont and stage > 0:
            kin = k1 if stage == 1 else (k2 if stage == 2 else k3)
            for j in range(NX_PHYS, nx):
                xs[j] = x[j] + c * kin[j]
        if stage > 0:
            turned = turned or stage_turns(pd, pd + c * s1, qd, qd + c * s3)
        s0, s1, s2, s3, s4, s5, _, _, _, _ = rhs_phys_serial(
            t + c, p + c * s0, pd + c * s1, q + c * s2, qd + c * s3, cur + c * s4, xi + c * s5, s,
            P, T, iref, x if stage == 0 else xs, kout)
        if stage == 0:
            g1, g3 = s1, s3
        u0 += w * s0
        u1 += w * s1
        u2 += w * s2
        u3 += w * s3
        u4 += w * s4
        u5 += w * s5
    sixth = h / 6.0
    if cont:
        for j in range(NX_PHYS, nx):
            x[j] += sixth * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    return (p + sixth * u0, pd + sixth * u1, q + sixth * u2, qd + sixth * u3, cur + sixth * u4, xi + sixth * u5,
            g1, g3, turned)


@jit
def rk4_step(t, h, p, pd, q, qd, cur, xi, s, P, T, iref, cont, x, xs, k1, k2, k3, k4):
    """One classical RK4 step (:func:`_rk4_scalars`); returns the advanced ``(p, pd, q, qd, cur, xi)``."""
    r = _rk4_scalars(t, h, p, pd, q, qd, cur, xi, s, P, T, iref, cont, x, xs, k1, k2, k3, k4)
    return r[0], r[1], r[2], r[3], r[4], r[5]


@inline
def _crossing(v, v_new, v_lin):
    """Fraction of the step where a speed v reaches 0: from the first stage's slope (its
    linear prediction v_lin at the step's end), else from the step's result v_new; 1.0 for
    none. RK4's later stages straddle the friction's jump and may hide a reversal from the
    result (the stages on the far side push the speed back), so the slope at the step's start
    decides first."""
    if v * v_lin < 0.0:
        return v / (v - v_lin)
    if v * v_new < 0.0:
        return v / (v - v_new)
    return 1.0


@inline
def reversal(pd, pd_new, pd_lin, qd, qd_new, qd_lin, P, rigid):
    """Where within the step a node carrying friction reverses its speed: the fraction of the
    step (1.0: no reversal, :func:`_crossing`) and the node (0 the motor side, 1 the load).
    ``*_new`` are the step's results, ``*_lin`` the speeds its first stage's slopes predict. A
    speed landing exactly on 0 is no reversal: the next step starts at rest."""
    frac, node = 1.0, -1
    if P[TS_M] > 0.0 or (rigid and P[TS_L] > 0.0):
        frac = _crossing(pd, pd_new, pd_lin)
        node = 0 if frac < 1.0 else -1
    if not rigid and P[TS_L] > 0.0:
        f = _crossing(qd, qd_new, qd_lin)
        if f < frac:
            frac, node = f, 1
    return frac, node


@inline
def switch_ahead(pd, pd_new, pd_lin, qd, qd_new, qd_lin, P, rigid):
    """Whether a node carrying friction may switch within the step: reverses
    (:func:`reversal`) or, at rest at the step's start, moves at its end (a breakaway).
    Cheap, inlined in the step loop (which also hands over a step one of whose stages left
    a node's direction: :func:`stage_turns`); :func:`.switch_loop.switched_step` then decides and does
    the work."""
    frac, _ = reversal(pd, pd_new, pd_lin, qd, qd_new, qd_lin, P, rigid)
    if frac < 1.0:
        return True
    if pd == 0.0 and pd_new != 0.0 and (P[TS_M] > 0.0 or (rigid and P[TS_L] > 0.0)):
        return True
    return not rigid and qd == 0.0 and qd_new != 0.0 and P[TS_L] > 0.0


@inline
def stage_turns(pd, pd_stage, qd, qd_stage):
    """Whether an RK4 stage's speeds left a node's direction at the step's start (its
    friction then jumped within the step)."""
    return pd * pd_stage < 0.0 or qd * qd_stage < 0.0


@jit  # the rest of a split step
def rk4_checked(t, h, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x, xs, k1, k2, k3, k4):
    """:func:`rk4_step` that also tells whether a node carrying friction may switch within the
    step, by the fixed-step loops' own test: :func:`switch_ahead` from the first stage's slopes
    and the result, or a stage whose speed left a node's direction (:func:`stage_turns`).
    Returns ``(p, pd, q, qd, cur, xi, ahead)``."""
    p1, pd1, q1, qd1, cur1, xi1, g1, g3, turned = _rk4_scalars(t, h, p, pd, q, qd, cur, xi, s, P, T, iref, cont,
                                                               x, xs, k1, k2, k3, k4)
    ahead = turned or switch_ahead(pd, pd1, pd + h * g1, qd, qd1, qd + h * g3, P, rigid)
    return p1, pd1, q1, qd1, cur1, xi1, ahead


@jit
def _trial(t, h, p, pd, q, qd, cur, xi, s, W, T, iref, cont, x, x0, xs, k1, k2, k3, k4):
    """An RK4 step of length h from the step's start with the parameters W (x[7:] restored
    from x0 first when they move)."""
    if cont:
        for j in range(NX_PHYS, x.size):
            x[j] = x0[j]
    return rk4_step(t, h, p, pd, q, qd, cur, xi, s, W, T, iref, cont, x, xs, k1, k2, k3, k4)


@jit
def _held_moment(t, h, p, pd, q, qd, cur, xi, s, H, Z, T, iref, cont, x, x0, xs, k1, k2, k3, k4, node):
    """The held node's signed breakaway distance over its inertia (Z: ``HOLD_GAUGE`` = 1)
    after a step of length h with the node held at rest."""
    r = _trial(t, h, p, pd, q, qd, cur, xi, s, H, T, iref, cont, x, x0, xs, k1, k2, k3, k4)
    d = rhs_phys_serial(t + h, r[0], r[1], r[2], r[3], r[4], r[5], s, Z, T, iref, x, k1)
    return d[1] if node == 0 else d[3]


@inline
def illinois_trial(a, b, ga, gb):
    """The Illinois method's next trial on [a, b] (g(a) g(b) < 0): ``(closed, c)``, closed
    once the bracket is within TAU_TOL of b (the search ends there), else c the secant's zero
    (the midpoint when it falls outside the bracket)."""
    if b - a <= TAU_TOL * (b if b > 0.0 else 1.0):
        return True, b
    c = b - gb * (b - a) / (gb - ga)
    if not (a < c < b):
        c = 0.5 * (a + b)
    return False, c


@inline
def illinois_next(a, b, ga, gb, c, gc, side):
    """The Illinois method's bracket after a trial c with value gc: c replaces the end whose
    value has gc's sign, and the other end's value is halved when the same end is replaced
    twice running (``side``: the end replaced last, 1 for b, -1 for a, 0 before any).
    Returns ``(a, b, ga, gb, side)``."""
    if (gc > 0.0) == (gb > 0.0):
        return a, c, (0.5 * ga if side == 1 else ga), gc, 1
    return c, b, gc, (0.5 * gb if side == -1 else gb), -1


@jit
def _illinois(a, b, ga, gb, t, p, pd, q, qd, cur, xi, s, W, H, Z, T, iref, cont, x, x0, xs, k1, k2, k3, k4,
              node, breakaway):
    """The zero of g on [a, b] (g(a) g(b) < 0) by the Illinois method: g the node's speed
    after a trial step with W (a reversal), else the held node's breakaway distance (a
    breakaway, :func:`_held_moment`)."""
    side = 0
    for _ in range(MAX_ITER):
        closed, c = illinois_trial(a, b, ga, gb)
        if closed:
            break
        if breakaway:
            gc = _held_moment(t, c, p, pd, q, qd, cur, xi, s, H, Z, T, iref, cont, x, x0, xs, k1, k2, k3, k4, node)
        else:
            r = _trial(t, c, p, pd, q, qd, cur, xi, s, W, T, iref, cont, x, x0, xs, k1, k2, k3, k4)
            gc = r[1] if node == 0 else r[3]
        if gc == 0.0:
            return c
        a, b, ga, gb, side = illinois_next(a, b, ga, gb, c, gc, side)
    return a if breakaway else b  # a breakaway: still held at a; a reversal: just past the zero


@jit
def first_switch(t, dt, p, pd, q, qd, cur, xi, s, P, T, iref, cont, rigid, x, xs, k1, k2, k3, k4, pd_new, qd_new,
                 x0, PW):
    """The first switch within the step from t (module doc): ``(True, p, pd, q, qd, cur, xi,
    tau)`` the state at t + tau just after it (RK4 to tau, the node at rest there or leaving
    it; x[7:] advanced to t + tau), else ``(False, ...)`` with the step's result (the
    continued motion, or the node held all through) and tau = dt."""
    for j in range(x.size):
        x0[j] = x[j]
    load = not rigid and P[TS_L] > 0.0  # the load carries friction of its own
    motor = P[TS_M] > 0.0 or (rigid and P[TS_L] > 0.0)
    node = -1
    if motor and pd == 0.0 and pd_new != 0.0:
        node = 0
    elif load and qd == 0.0 and qd_new != 0.0:
        node = 1
    breakaway = node >= 0
    W, H, Z = PW[0], PW[1], PW[2]
    for j in range(P.size):
        # the trial parameters: a reversing node's friction held at its direction (W); a
        # breakaway: the node held at rest (H), the node's breakaway distance (then its side)
        # in place of its acceleration (Z)
        W[j] = H[j] = Z[j] = P[j]
    Z[HOLD_GAUGE] = 1.0
    tau = 0.0
    if not breakaway:
        W[DIR_M] = 0.0 if pd == 0.0 else (1.0 if pd > 0.0 else -1.0)
        W[DIR_L] = 0.0 if (rigid or qd == 0.0) else (1.0 if qd > 0.0 else -1.0)
        r = _trial(t, dt, p, pd, q, qd, cur, xi, s, W, T, iref, cont, x, x0, xs, k1, k2, k3, k4)
        if motor and pd * r[1] < 0.0:
            node, g0, g1 = 0, pd, r[1]
        elif load and qd * r[3] < 0.0:
            node, g0, g1 = 1, qd, r[3]
        else:  # the continued motion does not reverse within the step: it is the step (a stage of
            # the plain step that crossed a speed's zero made the friction jump there)
            return False, r[0], r[1], r[2], r[3], r[4], r[5], dt
        tau = _illinois(0.0, dt, g0, g1, t, p, pd, q, qd, cur, xi, s, W, H, Z, T, iref, cont, x, x0, xs,
                        k1, k2, k3, k4, node, False)
        if node == 0 and load and qd * r[3] < 0.0:  # both reverse along the continued motion: the earlier
            tau_l = _illinois(0.0, dt, qd, r[3], t, p, pd, q, qd, cur, xi, s, W, H, Z, T, iref, cont, x, x0, xs,
                              k1, k2, k3, k4, 1, False)
            if tau_l < tau:
                tau, node = tau_l, 1
    else:
        if node == 0:
            H[TS_M] = HELD
        else:
            H[TS_L] = HELD
        g1 = _held_moment(t, dt, p, pd, q, qd, cur, xi, s, H, Z, T, iref, cont, x, x0, xs, k1, k2, k3, k4, node)
        if g1 <= 0.0:  # held at the step's end: at rest all through it (a stage of the plain
            # step, from its estimate of the state, broke away too early)
            r = _trial(t, dt, p, pd, q, qd, cur, xi, s, H, T, iref, cont, x, x0, xs, k1, k2, k3, k4)
            return False, r[0], r[1], r[2], r[3], r[4], r[5], dt
        g0 = _held_moment(t, 0.0, p, pd, q, qd, cur, xi, s, H, Z, T, iref, cont, x, x0, xs, k1, k2, k3, k4,
                          node)
        if g0 < 0.0:
            tau = _illinois(0.0, dt, g0, g1, t, p, pd, q, qd, cur, xi, s, W, H, Z, T,
                            iref, cont, x, x0, xs, k1, k2, k3, k4, node, True)
    # RK4 to tau (the continued motion, or held at rest), the node at rest there
    r = _trial(t, tau, p, pd, q, qd, cur, xi, s, H if breakaway else W, T, iref, cont, x, x0, xs, k1, k2, k3, k4)
    p, pd, q, qd, cur, xi = r
    if node == 0:
        pd = 0.0
        if rigid:
            qd = 0.0
    else:
        qd = 0.0
    if breakaway:  # the side it breaks away to, at tau
        Z[HOLD_GAUGE] = 2.0
        d = rhs_phys_serial(t + tau, p, pd, q, qd, cur, xi, s, Z, T, iref, x, k1)
        slide = d[1] if node == 0 else d[3]
    else:  # at rest at the reversal: stuck, or breaking away the other way at once
        d = rhs_phys_serial(t + tau, p, pd, q, qd, cur, xi, s, P, T, iref, x, k1)
        slide = d[1] if node == 0 else d[3]
    if slide != 0.0:
        # breaking away: the node leaves rest sliding (SEED in the moment's direction), so every
        # stage of the rest of the step sees the sliding friction at 0+ (Ts on the Stribeck
        # curve, Tc at once without a Stribeck speed), not the law at rest
        v = SEED if slide > 0.0 else -SEED
        if node == 0:
            pd = v
            if rigid:
                qd = v
        else:
            qd = v
    return True, p, pd, q, qd, cur, xi, tau
