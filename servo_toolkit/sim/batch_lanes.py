"""The batched variants in SIMD lanes: blocks of :data:`W` variants advanced in lockstep.

A block keeps its variants' physical states in structure-of-arrays form (one row per state,
one column per lane) and evaluates each RK4 stage as one loop across the lanes around the
inlined right-hand side (:func:`kernel.rhs_phys` with ``lanes=True``, which leaves out the
branches a block in lanes never takes), which LLVM vectorizes (AVX-512: the whole block in
one register per quantity). The physics is the single run's: the same right-hand side, the same controller sample (each lane's
measurements by :func:`kernel.controller_inputs`, then the state-space update of
:func:`kernel.controller_update` across the lanes by :func:`kernel.motion_columns`, at the
reference r(t) the block shares) and the same RK4 stage arithmetic
(:func:`integrators.rk4_coefficients`). Per variant the block keeps the
figures and snapshots of :func:`batch.variant_run`; a variant that stops (non-finite state,
stroke end) is masked out while its block-mates go on. An open-loop lane's command is evaluated
once per stage outside the vectorized loop (inside it, LLVM would evaluate its sine in every
lane, closed-loop ones included), and the per-step figures are kept across the lanes, with a
scalar pass only for a lane with a new peak, a state that may stop it, or its last step.
Friction that holds (``STICK``) runs
in the lanes: its stick and breakaway law is branch-free in the right-hand side, and a lane
whose node reverses its speed or breaks away within a step has that step redone by the
single run's split step (:func:`switch_loop.switched_step`, from the same first-stage slopes
and results) while its block-mates take the plain update. A block holding a continuous
controller, a cam, a feedforward or controllers of different structures falls back to
:func:`batch.variant_run` per variant.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numba.core import cgutils, types
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

from . import layout as lo
from .batch import variant_run
from .integrators import rk4_coefficients, snapshot as _snap, step_status
from .split_step import stage_turns, switch_ahead
from .switch_loop import switched_step
from .layout import F_CUR, F_ERR, F_SAT, F_STATUS, F_STEP, F_TAU, S_DEFLECTION, S_END, S_PEAK
from .kernel import FASTMATH, clip, command, controller_inputs, motion_columns, reference, rhs_phys

#: the lanes' fast-math flags: the kernel's without reassociation and contraction, which
#: LLVM applied differently to the same code compiled here and loaded from the cache (the
#: results then differed in the last bit between processes)
LANE_MATH = FASTMATH - {"reassoc", "contract"}
jit = nb.njit(cache=True, fastmath=LANE_MATH, error_model="numpy")
#: lanes per block: one AVX-512 register of float64 (two AVX2 registers)
W = 8
#: parameter slots of the reference r(t), shared by a block when equal in all its variants
REF_SLOTS = (lo.REF_KIND, lo.REF_A, lo.REF_F, lo.REF_OFF, lo.REF_T0, *range(lo.REF_TAB_OFF, lo.REF_TAB_SUM + 1))
#: the controller's structure (state count and coefficient offsets), which the lanes' state-space
#: update (:func:`kernel.motion_columns`) takes from the block's first variant
CONTROLLER_SLOTS = (lo.NC, lo.OFF_A, lo.OFF_B, lo.OFF_C, lo.OFF_D)


@jit
def block_kind(P, v0, nl):
    """(lanes allowed, reference shared) for the variants v0 .. v0 + nl - 1: lanes need a
    sampled or open-loop controller of one structure, no cam, the two-mass chain and no
    feedforward (it runs variant by variant, :func:`batch.variant_run`, whose controller
    sample adds it) in every variant. A rigid chain runs variant by variant too: in lanes its
    branch, with its own losses, cost every two-mass block its selects (and a block kind of
    its own, a compiled copy of the stage; one variant at a time is within 10 % of the lanes)."""
    lanes = True
    shared = True
    for v in range(v0, v0 + nl):
        if (int(P[v, lo.CMODE]) == lo.CONTINUOUS or P[v, lo.CAM] > 0.0 or P[v, lo.NMID] > 0.0
                or P[v, lo.FF_ON] > 0.0 or P[v, lo.RIGID] > 0.0):
            lanes = False
        for j in CONTROLLER_SLOTS:
            if P[v, j] != P[v0, j]:
                lanes = False
        for j in REF_SLOTS:
            if P[v, j] != P[v0, j]:
                shared = False
    return lanes, shared


#: the stage loop is compiled without reference counting: a lane's parameter column and
#: tables are views, whose counting calls would keep the loop from vectorizing
_lane_jit = nb.njit(cache=True, fastmath=LANE_MATH, error_model="numpy", _nrt=False)


@intrinsic
def _stack_matrix(typingctx, rows, cols):
    """A (rows, cols) float64 array (literal sizes) on the caller's stack, unmanaged."""
    if not (isinstance(rows, types.IntegerLiteral) and isinstance(cols, types.IntegerLiteral)):
        return None
    n_rows, n_cols = rows.literal_value, cols.literal_value
    array_type = types.Array(types.float64, 2, "C")

    def codegen(context, builder, signature, args):
        data = cgutils.alloca_once(builder, context.get_data_type(types.float64), size=n_rows * n_cols)
        intp = context.get_value_type(types.intp)
        ary = make_array(array_type)(context, builder)
        populate_array(ary, data=data, shape=[intp(n_rows), intp(n_cols)], strides=[intp(8 * n_cols), intp(8)],
                       itemsize=intp(8), meminfo=None)
        return ary._getvalue()
    return array_type(rows, cols), codegen


@intrinsic
def _packed(typingctx, arr):
    """The C-contiguous array ``arr`` with its strides rebuilt from its shape, the last one a
    constant: LLVM then sees consecutive lanes in consecutive memory (vector loads, not
    gathers)."""
    if not (isinstance(arr, types.Array) and arr.layout == "C"):
        return None

    def codegen(context, builder, signature, args):
        src = make_array(arr)(context, builder, value=args[0])
        shape = cgutils.unpack_tuple(builder, src.shape, arr.ndim)
        intp = context.get_value_type(types.intp)
        stride = intp(context.get_abi_sizeof(context.get_data_type(arr.dtype)))
        strides = [stride]
        for dim in reversed(shape[1:]):
            strides.insert(0, builder.mul(strides[0], dim))
        out = make_array(arr)(context, builder)
        populate_array(out, data=src.data, shape=shape, strides=strides, itemsize=src.itemsize,
                       meminfo=src.meminfo)
        return out._getvalue()
    return arr(arr), codegen


@intrinsic
def _column(typingctx, arr, lane):
    """Column ``lane`` of a C-contiguous (n, W) float64 array as a 1-D view whose stride is the
    constant W: a parameter read across the lanes is then one vector load."""
    if not (isinstance(arr, types.Array) and arr.ndim == 2 and arr.layout == "C" and arr.dtype == types.float64):
        return None
    column_type = types.Array(types.float64, 1, "A")

    def codegen(context, builder, signature, args):
        src = make_array(arr)(context, builder, value=args[0])
        intp = context.get_value_type(types.intp)
        out = make_array(column_type)(context, builder)
        populate_array(out, data=builder.gep(src.data, [args[1]]),
                       shape=[cgutils.unpack_tuple(builder, src.shape, 2)[0]], strides=[intp(8 * W)],
                       itemsize=src.itemsize, meminfo=src.meminfo)
        return out._getvalue()
    return column_type(arr, types.intp), codegen


@_lane_jit
def _stage(tc, c, w, stage, Y, S, U, A, PT, T, TI, IREF, dummy, holds, TURN):
    """RK4 stage ``stage`` across the lanes: slopes S from the states Y + c S, accumulated into
    U with weight w (the first stage also keeps current, voltage, i_ref and torque in A).
    ``holds`` (a literal at each call: one compiled stage for blocks with friction that
    holds, one without, so a block without it pays nothing for its selects) compiles in
    friction that holds; then ``TURN`` marks a lane whose stage speeds left a node's
    direction at the step's start (:func:`split_step.stage_turns`).

    The lane loop writes to the stack only (LLVM then knows no store can alias the tables it
    gathers from, which it could not check at run time) and the results are copied out.
    """
    out = _stack_matrix(10, W)
    Y, S, U, A, PT, T, TI, IREF = (_packed(Y), _packed(S), _packed(U), _packed(A), _packed(PT), _packed(T),
                                   _packed(TI), _packed(IREF))
    for l in range(W):
        s0, s1, s2, s3, s4, s5, i_, v_, r_, tau_ = rhs_phys(
            tc, Y[0, l] + c * S[0, l], Y[1, l] + c * S[1, l], Y[2, l] + c * S[2, l],
            Y[3, l] + c * S[3, l], Y[4, l] + c * S[4, l], Y[5, l] + c * S[5, l], Y[6, l],
            _column(PT, l), T[TI[l]], IREF[l], dummy, dummy, True, holds)
        out[0, l], out[1, l], out[2, l], out[3, l], out[4, l], out[5, l] = s0, s1, s2, s3, s4, s5
        out[6, l], out[7, l], out[8, l], out[9, l] = i_, v_, r_, tau_
    for l in range(W):
        if holds and stage > 0 and stage_turns(Y[1, l], Y[1, l] + c * S[1, l], Y[3, l], Y[3, l] + c * S[3, l]):
            TURN[l] = 1.0
        for k in range(6):
            S[k, l] = out[k, l]
            U[k, l] = w * out[k, l] if stage == 0 else U[k, l] + w * out[k, l]
        if stage == 0:
            for k in range(4):
                A[k, l] = out[6 + k, l]


@_lane_jit
def _control(t, r, shared, Y, PT, T, TI, IREF, ACT, XN):
    """The sampled controller of every running lane, the single run's
    (:func:`kernel.controller_update`): each lane's measurements
    (:func:`kernel.controller_inputs` on its state column ``Y[:, l]`` and parameter column
    ``PT[:, l]``), then the state-space update across the lanes
    (:func:`kernel.motion_columns`, vectorized), at the shared reference r or the lane's own
    r(t), with the clamp's back-calculation (``AW``) of a lane whose output is clamped.
    ``XN`` holds at least the controller's state count rows."""
    Y, PT, TI = _packed(Y), _packed(PT), _packed(TI)
    R = _stack_matrix(1, W)[0]
    TH = _stack_matrix(1, W)[0]
    WM = _stack_matrix(1, W)[0]
    YC = _stack_matrix(1, W)[0]
    for l in range(W):
        R[l], TH[l], WM[l] = 0.0, 0.0, 0.0
        if ACT[l] > 0.0:
            pc = _column(PT, l)
            R[l] = r if shared else reference(t, pc)
            TH[l], WM[l] = controller_inputs(_column(Y, l), pc, T[TI[l]])
    motion_columns(Y, PT, R, TH, WM, YC, XN, W)
    nc = int(PT[lo.NC, 0])
    for l in range(W):  # stopped lanes keep the state they stopped in
        if ACT[l] > 0.0:
            o = int(PT[lo.AW, l])
            if o > 0 and abs(YC[l]) > PT[lo.ILIM, l]:
                # back-calculation at the clamp, as the single run's controller_update
                excess = clip(YC[l], PT[lo.ILIM, l]) - YC[l]
                for j in range(nc):
                    XN[j, l] += PT[o + j, l] * excess
            for j in range(nc):
                Y[lo.NX_PHYS + j, l] = XN[j, l]
            IREF[l] = clip(YC[l], PT[lo.ILIM, l])


@jit
def block_run(X, P, T, tix, v0, nl, dt, n_steps, sub, shared, figs, snaps):
    """Variants v0 .. v0 + nl - 1 (nl <= W) in lanes: as :func:`batch.variant_run` for each
    (same arguments, rows of the batch), with the reference computed once per step when
    ``shared``."""
    nx = X.shape[1]
    n_par = P.shape[1]
    PT = np.empty((n_par, W))  # parameters, a column per lane (unused lanes repeat the last)
    TI = np.empty(W, dtype=np.int64)
    Y = np.empty((nx, W))  # states, a column per lane (the controller's after the physical)
    for l in range(W):
        v = v0 + min(l, nl - 1)
        TI[l] = tix[v]
        for j in range(n_par):
            PT[j, l] = P[v, j]
        for j in range(nx):
            Y[j, l] = X[v, j]
    S = np.zeros((6, W))
    U = np.zeros((6, W))
    A = np.zeros((4, W))
    IREF = np.zeros(W)
    ACT = np.zeros(W)  # 1.0 while the lane runs
    for l in range(nl):
        ACT[l] = 1.0
    fig = np.zeros((6, W))  # per lane: max |err|, max |i|, sat, max |tau|, max |p - q|
    for l in range(W):
        fig[1, l] = -1.0
        fig[4, l] = -1.0
    RL = np.zeros(W)  # each lane's reference when the block does not share one
    NEW = np.zeros(W)  # 1.0: a lane with a new peak current or deflection, or a state to check
    dummy = np.zeros(max(nx, 1))
    XN = np.empty((max(nx - lo.NX_PHYS, 1), W))  # the controller's next states
    G = np.zeros((2, W))  # the first stage's slopes of the node speeds (speed reversals)
    SPLIT = np.zeros(W)  # 1.0 for a lane whose step was split at a switch
    TURN = np.zeros(W)  # 1.0 for a lane one of whose stages left a node's direction
    stick = False
    open_loop = False
    for v in range(v0, v0 + nl):
        stick = stick or P[v, lo.STICK] > 0.0
        open_loop = open_loop or int(P[v, lo.CMODE]) == lo.OPEN_LOOP
    # what the right-hand side takes as the held i_ref: the controller's, or for an open-loop
    # lane its command's part (evaluated here, once per lane and stage, not in the lanes' loop)
    H = np.zeros(W) if open_loop else IREF
    xw, xs = np.empty(nx), np.empty(nx)  # a lane's state and stage state for a split step
    k1, k2, k3, k4 = np.empty(nx), np.empty(nx), np.empty(nx), np.empty(nx)
    x0, PW = np.empty(nx), np.empty((4, max(n_par, nx)))  # the split step's scratch
    to_sample = 0
    sixth = dt / 6.0
    running = nl
    r = 0.0
    for step in range(n_steps + 1):
        t = step * dt
        if shared:
            r = reference(t, P[v0])
        if sub > 0:
            if to_sample == 0:
                _control(t, r, shared, Y, PT, T, TI, IREF, ACT, XN)
                to_sample = sub
            to_sample -= 1
        # one call site of the stage per friction model (its code compiles once for each): stage 0
        # also keeps the figures
        for stage in range(4):
            c, w = rk4_coefficients(stage, dt)
            if stage == 0:
                S[:, :] = 0.0
            if open_loop:
                for l in range(nl):
                    pv = P[v0 + l]
                    H[l] = command(t + c, pv) - pv[lo.REF_OFF] if int(pv[lo.CMODE]) == lo.OPEN_LOOP else IREF[l]
            if stick:
                _stage(t + c, c, w, stage, Y, S, U, A, PT, T, TI, H, dummy, True, TURN)
            else:
                _stage(t + c, c, w, stage, Y, S, U, A, PT, T, TI, H, dummy, False, TURN)
            if stage > 0:
                continue
            if not shared:
                for l in range(nl):
                    RL[l] = reference(t, P[v0 + l]) if ACT[l] > 0.0 else 0.0
            # the figures every lane keeps, across the lanes (a stopped lane's are no longer
            # read), and which lanes need more: a new peak current or deflection (a snapshot),
            # or a state that may stop the run (the test of :func:`integrators.step_status`)
            for l in range(W):
                G[0, l], G[1, l] = S[1, l], S[3, l]
                err = abs(Y[2, l] - (r if shared else RL[l]))
                fig[0, l] = err if err > fig[0, l] else fig[0, l]
                tau = abs(A[3, l])
                fig[3, l] = tau if tau > fig[3, l] else fig[3, l]
                if abs(A[2, l]) >= PT[lo.ILIM, l] or abs(A[1, l]) >= PT[lo.VLIM, l]:
                    fig[2, l] = 1.0
                acc = Y[0, l] + Y[1, l] + Y[2, l] + Y[3, l] + Y[4, l] + Y[5, l] + Y[6, l]
                for j in range(lo.NX_PHYS, nx):
                    acc += Y[j, l]
                qo = Y[2, l]  # the load's angle: a block in lanes holds two-mass chains only
                alarm = not (math.isfinite(acc) and math.isfinite(tau)) or (
                    PT[lo.STROKE_MODE, l] == 0.0 and (qo > PT[lo.STROKE_HI, l] or qo < PT[lo.STROKE_LO, l]))
                NEW[l] = 1.0 if alarm or abs(A[0, l]) > fig[1, l] or abs(Y[0, l] - Y[2, l]) > fig[4, l] else 0.0
            for l in range(nl):
                if ACT[l] == 0.0 or (NEW[l] == 0.0 and step < n_steps):
                    continue
                v = v0 + l
                x = Y[:, l]
                p, pd, q, qd, cur, xi, s = Y[0, l], Y[1, l], Y[2, l], Y[3, l], Y[4, l], Y[5, l], Y[6, l]
                if abs(A[0, l]) > fig[1, l]:
                    fig[1, l] = abs(A[0, l])
                    _snap(snaps[v], S_PEAK, p, pd, q, qd, A[0, l], xi, s, x, t, IREF[l])
                defl = abs(p - q)
                if defl > fig[4, l]:
                    fig[4, l] = defl
                    _snap(snaps[v], S_DEFLECTION, p, pd, q, qd, cur, xi, s, x, t, IREF[l])
                status = step_status(p, pd, q, qd, cur, xi, s, x, abs(A[3, l]), P[v], P[v, lo.STROKE_MODE] == 0.0,
                                     P[v, lo.RIGID] > 0.0)
                if status != lo.OK or step == n_steps:
                    ACT[l] = 0.0
                    running -= 1
                    for j in range(nx):
                        X[v, j] = Y[j, l]
                    _snap(snaps[v], S_END, p, pd, q, qd, cur, xi, s, x, t, IREF[l])
                    figs[v, F_STATUS] = status
                    figs[v, F_STEP] = step
                    figs[v, F_ERR] = fig[0, l]
                    figs[v, F_CUR] = fig[1, l]
                    figs[v, F_SAT] = fig[2, l]
                    figs[v, F_TAU] = fig[3, l]
            if running == 0:
                break
        if running == 0:
            break
        if stick:
            _split_reversals(t, dt, v0, nl, Y, U, G, P, T, TI, IREF, ACT, SPLIT, TURN, xw, xs, k1, k2, k3, k4, x0, PW)
        for l in range(W):  # stopped lanes keep the state they stopped in, split ones their split step's
            for j in range(6):
                Y[j, l] = Y[j, l] + sixth * U[j, l] if ACT[l] > 0.0 and SPLIT[l] == 0.0 else Y[j, l]
            SPLIT[l] = 0.0
            TURN[l] = 0.0


@jit
def _split_reversals(t, dt, v0, nl, Y, U, G, P, T, TI, IREF, ACT, SPLIT, TURN, xw, xs, k1, k2, k3, k4, x0, PW):
    """Friction that holds, per lane: a running lane whose node carrying friction reverses its
    speed or breaks away within the step (:func:`split_step.switch_ahead`, from the step's
    result and its first stage's slopes ``G``, as the single run decides) has its step redone
    by :func:`switch_loop.switched_step`; its new state goes into ``Y`` and ``SPLIT`` marks it,
    so the plain update leaves it alone."""
    sixth = dt / 6.0
    nx = xw.size
    for l in range(nl):
        v = v0 + l
        if ACT[l] == 0.0 or P[v, lo.STICK] <= 0.0:
            continue
        rigid = P[v, lo.RIGID] > 0.0
        pd, qd = Y[1, l], Y[3, l]
        pd_new, pd_lin = pd + sixth * U[1, l], pd + dt * G[0, l]
        qd_new, qd_lin = qd + sixth * U[3, l], qd + dt * G[1, l]
        if TURN[l] > 0.0 or switch_ahead(pd, pd_new, pd_lin, qd, qd_new, qd_lin, P[v], rigid):
            for j in range(nx):
                xw[j] = Y[j, l]
            Y[0, l], Y[1, l], Y[2, l], Y[3, l], Y[4, l], Y[5, l] = switched_step(
                t, dt, Y[0, l], Y[1, l], Y[2, l], Y[3, l], Y[4, l], Y[5, l], Y[6, l], P[v], T[TI[l]], IREF[l],
                False, rigid, xw, xs, k1, k2, k3, k4, pd_new, qd_new, x0, PW, True, 0)
            SPLIT[l] = 1.0


@nb.njit(parallel=True, cache=True, fastmath=LANE_MATH, error_model="numpy")
def run_lanes(X, P, T, tix, dt, n_steps, sub, figs, snaps):
    """:func:`batch.run_variants` by blocks of :data:`W` variants in lanes (in parallel
    across blocks); a block that cannot run in lanes runs variant by variant."""
    nv = X.shape[0]
    for b in nb.prange((nv + W - 1) // W):
        v0 = b * W
        nl = min(W, nv - v0)
        lanes, shared = block_kind(P, v0, nl)
        if lanes:
            block_run(X, P, T, tix, v0, nl, dt, n_steps, sub, shared, figs, snaps)
        else:
            for v in range(v0, v0 + nl):
                variant_run(X[v], P[v], T[tix[v]], dt, n_steps, sub, figs[v], snaps[v])
