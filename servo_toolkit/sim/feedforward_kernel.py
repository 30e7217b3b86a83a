"""The feedforward current inside the compiled kernels: the reference's analytic derivatives
and the rigid chain's inverse dynamics along the commanded trajectory
(:class:`servo_toolkit.loop.controller.Feedforward`; slots in :mod:`servo_toolkit.sim.layout`)."""

from __future__ import annotations

import math

from ..core.jit_cache import install as _install_cache

_install_cache()  # noqa: E402 - before any kernel below is decorated

from .layout import (BM, ETA_MEAN, FF_JSCALE, FF_KA, FF_KV, FF_LEAD, FF_MODEL, FF_SPEED, HINGE_D,  # noqa: E402
                     HINGE_K, HINGE_M, INV_H, INV_TAU_S, JW, KT, REF_A, REF_F, REF_KIND,
                     REF_OFF, REF_RAMP, REF_SINE, REF_STEP, REF_T0, REF_TABLE, T_J, T_N, TAB_H, TC, WS,
                     FF_DJ, REF_MOVE)
from .command_kernel import impulse, impulses, move_rates  # noqa: E402
from .compliance_kernel import blend, inertia_beyond_motor  # noqa: E402
from .table_kernel import table_rates  # noqa: E402
from .tables import cell, interp  # noqa: E402
from .vmath import inline, tanh  # noqa: E402


@inline
def reference_rates(t, P):
    """The reference and its analytic first and second time derivatives at time t,
    ``(r, r', r'')``: the command's (:func:`command_rates`), through the command shaper when
    one is set (the same impulses shape r, r' and r'')."""
    r, rd, rdd = 0.0, 0.0, 0.0
    for i in range(impulses(P)):
        a, d = impulse(P, i)
        ri, rdi, rddi = command_rates(t - d, P)
        r += a * ri
        rd += a * rdi
        rdd += a * rddi
    return r, rd, rdd


@inline
def command_rates(t, P):
    """The command and its analytic first and second time derivatives at time t,
    ``(r, r', r'')``: a sine's, a move's, a ramp's rate (0 before it starts), a sampled
    command's interpolant (:func:`.table_kernel.table_rates`), 0 for a hold and a step (the
    step's impulses are not fed forward)."""
    kind = int(P[REF_KIND])
    if kind == REF_MOVE:
        return move_rates(t, P)
    if kind == REF_SINE:
        w = 2.0 * math.pi * P[REF_F]
        s = math.sin(w * (t - P[REF_T0]))
        c = math.cos(w * (t - P[REF_T0]))
        return P[REF_OFF] + P[REF_A] * s, P[REF_A] * w * c, -P[REF_A] * w * w * s
    if kind == REF_STEP:
        return P[REF_OFF] + (P[REF_A] if t >= P[REF_T0] else 0.0), 0.0, 0.0
    if kind == REF_RAMP:
        if t > P[REF_T0]:
            return P[REF_OFF] + P[REF_A] * (t - P[REF_T0]), P[REF_A], 0.0
        return P[REF_OFF], 0.0, 0.0
    if kind == REF_TABLE:
        return table_rates(t, P)
    return P[REF_OFF], 0.0, 0.0


@inline
def feedforward_current(r, rd, rdd, P, T):
    """The feedforward current (A) along the commanded trajectory r, r', r''
    (:class:`servo_toolkit.loop.controller.Feedforward`): the velocity and acceleration gains'
    terms plus, with ``FF_MODEL``, the rigid chain's inverse dynamics at r from the model's
    tables (J, J', N, N'; the inertia offset by ``FF_DJ``, the load the feedforward assumes
    less the model's), its loss by the direction of the power flow (:func:`lossy`'s
    coefficient, solved for the motor torque), the load's hinge moment and damping and the
    motor's viscous and smoothed Coulomb friction."""
    i = P[FF_KV] * rd + P[FF_KA] * rdd
    if P[FF_MODEL] > 0.0:
        kc, tc = cell(P, r)
        hc = P[TAB_H]
        ih = P[INV_H]
        j, dj = interp(T, T_J, kc, tc, hc, ih)
        n, dn = interp(T, T_N, kc, tc, hc, ih)
        jb, djb = inertia_beyond_motor(P, T, kc, tc, hc, ih)  # the whole chain's J(r), J'(r)
        j = (j + jb + P[FF_DJ]) * P[FF_JSCALE]
        dj = (dj + djb) * P[FF_JSCALE]
        m_load = -P[HINGE_M] - P[HINGE_K] * r - P[HINGE_D] * rd
        tq = j * rdd + 0.5 * dj * rd * rd - m_load
        if P[ETA_MEAN] > 0.0:
            jw = P[JW] * n * n * P[FF_JSCALE]
            tw = jw * rdd + P[JW] * P[FF_JSCALE] * n * dn * rd * rd
            tt = tq - tw
            sg = tanh(tt * P[INV_TAU_S]) * tanh(abs(n) * rd * P[WS])
            c = blend(P, sg)
            tq = tw + tt / (1.0 - c)
        wm = n * rd
        i += (tq / n + P[BM] * wm + P[TC] * tanh(wm * P[WS])) / P[KT]
    return i


@inline
def feedforward(t, P, T):
    """The reference and the feedforward at a controller sample at time t: ``(r, i_ff, w_ff)``.

    r = r(t) is the feedback's reference; ``w_ff`` the motor speed along the commanded
    trajectory, N(r) r'(t), which the speed loop takes as its reference (subtracted from the
    measured motor speed; 0 unless ``FF_SPEED``); ``i_ff`` the feedforward current
    (:func:`feedforward_current`) along the trajectory at t + ``FF_LEAD`` (half a sample: the
    middle of the interval over which the zero-order hold applies it).
    """
    r, rd, _ = reference_rates(t, P)
    w_ff = 0.0
    if P[FF_SPEED] > 0.0:
        kc, tc = cell(P, r)
        n, _ = interp(T, T_N, kc, tc, P[TAB_H], P[INV_H])
        w_ff = n * rd
    ra, rda, rdda = reference_rates(t + P[FF_LEAD], P)
    return r, feedforward_current(ra, rda, rdda, P, T), w_ff


__all__ = ["command_rates", "feedforward", "feedforward_current", "reference_rates"]
