"""Commands and gain schedule inside the compiled kernels: the position reference r(t) and
its command (sine, step, ramp, table), the jerk-limited move, the command shaper's impulses
and the gain schedule along the stroke (slots in
:mod:`servo_toolkit.sim.layout`; the host side in :mod:`servo_toolkit.loop.profile`,
:mod:`servo_toolkit.loop.shaper` and :mod:`servo_toolkit.loop.schedule`)."""

from __future__ import annotations

from ..core.jit_cache import install as _install_cache

_install_cache()  # noqa: E402 - before any kernel below is decorated

import math  # noqa: E402

from .layout import (REF_A, REF_F, REF_KIND, REF_MOVE, REF_OFF, REF_RAMP, REF_SINE, REF_STEP, REF_T0,  # noqa: E402
                     REF_TABLE, SCHED, SHAPE_A0, SHAPE_T1)
from .table_kernel import table_rates  # noqa: E402
from .vmath import inline  # noqa: E402


@inline
def move_rates(t, P):
    """The jerk-limited move (``REF_MOVE``) at time t: ``(r, r', r'')``.

    Seven segments from ``REF_T0``: jerk +j for the jerk time Tj, constant acceleration for
    Ta, jerk -j for Tj, constant speed for Tv, then the acceleration's mirror image
    (r(T - s) = D - r(s), r' even and r'' odd about the middle of the move); the start value
    ``REF_OFF`` before it, the end value after it. The block at ``P[REF_F]`` holds
    [signed jerk, Tj, Ta, Tv] (:class:`servo_toolkit.loop.profile.MoveProfile`).
    """
    o = int(P[REF_F])
    j, tj, ta, tv = P[o], P[o + 1], P[o + 2], P[o + 3]
    t3 = 2.0 * tj + ta  # end of the acceleration
    a = j * tj  # peak acceleration
    vp = a * (tj + ta)  # cruise speed
    p3 = 0.5 * vp * t3  # distance of the acceleration
    u = min(max(t - P[REF_T0], 0.0), 2.0 * t3 + tv)
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
    return P[REF_OFF] + p, v, acc


@inline
def impulses(P):
    """The command shaper's impulse count: 3 with a shaper (``SHAPE_A0`` > 0; a ZV's third
    amplitude is 0), else 1 (the command itself)."""
    return 3 if P[SHAPE_A0] > 0.0 else 1


@inline
def impulse(P, i):
    """Amplitude and delay (s) of impulse i of the command shaper; ``(1, 0)`` without one."""
    if P[SHAPE_A0] <= 0.0:
        return 1.0, 0.0
    return P[SHAPE_A0 + i], (0.0 if i == 0 else P[SHAPE_T1 + i - 1])


@inline
def schedule_factors(P, q):
    """The gain schedule's factors at the measured output position q: ``(g_e, g_w)``, the
    factor on the position-error inputs (theta_ref, theta) and on the speed input (omega_m)
    of the motion controller; (1, 1) without a schedule. Linear between the schedule's
    points, its end values held beyond them (the table a drive interpolates)."""
    o = int(P[SCHED])
    if o == 0:
        return 1.0, 1.0
    n = int(P[o])
    s = (q - P[o + 1]) * P[o + 2]
    if s <= 0.0:
        k, f = 0, 0.0
    elif s >= n - 1.0:
        k, f = n - 2, 1.0
    else:
        k = int(s)
        f = s - k
    e = o + 3 + k
    w = e + n
    return P[e] + f * (P[e + 1] - P[e]), P[w] + f * (P[w + 1] - P[w])


@inline
def reference(t, P):
    """The position reference at time t (evaluated inside the kernel): the command
    (:func:`command`, or the jerk-limited move of ``REF_MOVE``), through the command shaper
    when one is set (``SHAPE_A0`` > 0): sum_i A_i r(t - t_i) over its impulses
    (:mod:`servo_toolkit.loop.shaper`)."""
    move = int(P[REF_KIND]) == REF_MOVE
    r = 0.0
    for i in range(impulses(P)):  # one inlined command in the loop: the code stays small
        a, d = impulse(P, i)
        r += a * (move_rates(t - d, P)[0] if move else command(t - d, P))
    return r


@inline
def command(t, P):
    """The position command at time t, before the command shaper (the move,
    :func:`~.command_kernel.move_rates`, is a closed-loop command: :func:`reference`)."""
    kind = int(P[REF_KIND])
    if kind == REF_SINE:
        return P[REF_OFF] + P[REF_A] * math.sin(2.0 * math.pi * P[REF_F] * (t - P[REF_T0]))
    if kind == REF_STEP:
        return P[REF_OFF] + (P[REF_A] if t >= P[REF_T0] else 0.0)
    if kind == REF_RAMP:
        return P[REF_OFF] + P[REF_A] * max(t - P[REF_T0], 0.0)
    if kind == REF_TABLE:
        return table_rates(t, P)[0]
    return P[REF_OFF]


__all__ = ["command", "impulse", "impulses", "move_rates", "reference", "schedule_factors"]
