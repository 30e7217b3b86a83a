"""The position command of the transcribed right-hand side (tests/rhs_reference.py): the
command kinds of the kernels' ``command.h`` (servo_toolkit/_physics: hold, sine, step, ramp,
sampled table, jerk-limited move) with their analytic first and second time derivatives,
through the command shaper's impulses. Plain Python, written from
the kernels' equations; it calls no kernel."""

from __future__ import annotations

import math

from servo_toolkit.sim import layout as lo


def table_rates(t, P):
    """The sampled command and its first two time derivatives: REF_OFF plus the cubic
    Hermite interpolant of the samples (held before and after them, or periodic)."""
    o, n, inv = int(P[lo.REF_TAB_OFF]), int(P[lo.REF_TAB_N]), P[lo.REF_TAB_INV_DT]
    last = n - 1.0
    s = (t - P[lo.REF_TAB_T0]) * inv
    moving = 1.0
    if P[lo.REF_TAB_WRAP] > 0.0:
        s = s - last * math.floor(s / last)
    elif s <= 0.0:
        s, moving = 0.0, 0.0
    elif s >= last:
        s, moving = last, 0.0
    k = min(int(s), n - 2)
    u = s - k
    y0, y1 = P[o + k], P[o + k + 1]
    m0, m1 = P[o + n + k], P[o + n + k + 1]
    dy = y0 - y1
    u2 = u * u
    value = y0 + u2 * (2.0 * u - 3.0) * dy + (1.0 / inv) * ((u2 * u - 2.0 * u2 + u) * m0 + (u2 * u - u2) * m1)
    rate = (6.0 * u2 - 6.0 * u) * dy * inv + (3.0 * u2 - 4.0 * u + 1.0) * m0 + (3.0 * u2 - 2.0 * u) * m1
    accel = ((12.0 * u - 6.0) * dy * inv + (6.0 * u - 4.0) * m0 + (6.0 * u - 2.0) * m1) * inv
    return P[lo.REF_OFF] + value, moving * rate, moving * accel


def move_rates(t, P):
    """The jerk-limited move: jerk +j for Tj, constant acceleration for Ta, jerk -j for Tj,
    cruise for Tv, then the mirror image; ``(r, r', r'')``."""
    o = int(P[lo.REF_F])
    j, tj, ta, tv = P[o], P[o + 1], P[o + 2], P[o + 3]
    t3 = 2.0 * tj + ta
    a = j * tj
    vp = a * (tj + ta)
    p3 = 0.5 * vp * t3
    u = min(max(t - P[lo.REF_T0], 0.0), 2.0 * t3 + tv)
    back = u > t3 + tv
    if back:
        u = 2.0 * t3 + tv - u
    if u <= tj:
        p, v, acc = j * u * u * u / 6.0, 0.5 * j * u * u, j * u
    elif u <= tj + ta:
        w = u - tj
        p, v, acc = j * tj * tj * tj / 6.0 + 0.5 * j * tj * tj * w + 0.5 * a * w * w, 0.5 * j * tj * tj + a * w, a
    elif u <= t3:
        w = t3 - u
        p, v, acc = p3 - vp * w + j * w * w * w / 6.0, vp - 0.5 * j * w * w, j * w
    else:
        p, v, acc = p3 + vp * (u - t3), vp, 0.0
    if back:
        p, acc = 2.0 * p3 + vp * tv - p, -acc
    return P[lo.REF_OFF] + p, v, acc


def command_rates(t, P):
    """The command before the shaper and its analytic rates (a step's jump is not fed forward)."""
    kind = int(P[lo.REF_KIND])
    off, amp, t0 = P[lo.REF_OFF], P[lo.REF_A], P[lo.REF_T0]
    if kind == lo.REF_MOVE:
        return move_rates(t, P)
    if kind == lo.REF_SINE:
        w = 2.0 * math.pi * P[lo.REF_F]
        s, c = math.sin(w * (t - t0)), math.cos(w * (t - t0))
        return off + amp * s, amp * w * c, -amp * w * w * s
    if kind == lo.REF_STEP:
        return off + (amp if t >= t0 else 0.0), 0.0, 0.0
    if kind == lo.REF_RAMP:
        return (off + amp * (t - t0), amp, 0.0) if t > t0 else (off, 0.0, 0.0)
    if kind == lo.REF_TABLE:
        return table_rates(t, P)
    return off, 0.0, 0.0


def impulses(P):
    """The command shaper's (amplitude, delay) pairs; one unit impulse without a shaper."""
    if P[lo.SHAPE_A0] <= 0.0:
        return [(1.0, 0.0)]
    return [(P[lo.SHAPE_A0], 0.0), (P[lo.SHAPE_A1], P[lo.SHAPE_T1]), (P[lo.SHAPE_A2], P[lo.SHAPE_T2])]


def command(t, P):
    """The open loop's and the closed loop's position command at t (before the shaper)."""
    return command_rates(t, P)[0]


def reference(t, P):
    """r(t): the command (or the move) through the shaper, sum_i A_i r(t - t_i)."""
    return sum(a * command(t - d, P) for a, d in impulses(P))


def reference_rates(t, P):
    """(r, r', r'') through the shaper."""
    r = rd = rdd = 0.0
    for a, d in impulses(P):
        ri, rdi, rddi = command_rates(t - d, P)
        r, rd, rdd = r + a * ri, rd + a * rdi, rdd + a * rddi
    return r, rd, rdd
