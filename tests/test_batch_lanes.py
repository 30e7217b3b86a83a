"""The batched variants in SIMD lanes equal the per-variant loop: figures, final states and
snapshots, with a variant that stops mid-block (non-finite, stroke end) while its
block-mates go on, a partial last block, variants with their own tables and reference, and
the per-variant fallback of a continuous controller."""

import math

import numpy as np
import pytest

from servo_toolkit.sim import ModelOptions, Reference, build_model
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.batch import (F_CUR, F_ERR, F_SAT, F_STATUS, F_STEP, F_TAU, NFIG, NSNAP, S_END,
                                     S_PEAK, run_variants)
from servo_toolkit.sim.batch_lanes import W, block_kind, run_lanes
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.tables import frozen_tables
from servo_toolkit.sim.variants import VariantBuilder
from servo_toolkit.studies.time_run import sine_run_options


REF = Reference.sine(math.radians(2.0), 8.0)
DT = 1e-4
STEPS = 1500


def _both(P, T, tix, X0, sub, steps=STEPS):
    out = []
    for fn in (run_variants, run_lanes):
        X = np.array(X0, dtype=float)
        figs = np.zeros((len(X), NFIG))
        snaps = np.zeros((len(X), NSNAP, X.shape[1] + 2))
        fn(X, np.ascontiguousarray(P), frozen_tables(T), np.ascontiguousarray(tix, dtype=np.int64), DT,
           steps, sub, figs, snaps)
        out.append((X, figs, snaps))
    return out


def _assert_equal(one, lanes):
    (X1, f1, s1), (X2, f2, s2) = one, lanes
    np.testing.assert_array_equal(f2[:, F_STATUS], f1[:, F_STATUS])
    np.testing.assert_array_equal(f2[:, F_STEP], f1[:, F_STEP])
    np.testing.assert_array_equal(f2[:, F_SAT], f1[:, F_SAT])
    for col in (F_ERR, F_CUR, F_TAU):
        np.testing.assert_allclose(f2[:, col], f1[:, col], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(X2, X1, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(s2[:, S_END], s1[:, S_END], rtol=1e-9, atol=1e-12)
    # the peak-current snapshot holds that peak (a clamped current may reach it at
    # neighbouring steps that differ in the last bit, so its step is not compared)
    np.testing.assert_allclose(np.abs(s2[:, S_PEAK, 4]), f1[:, F_CUR], rtol=1e-12)


def _rows(scene, controller, n, options=None):
    options = options or sine_run_options(scene, controller, REF)[0]
    builder = VariantBuilder.create(scene, controller, options)
    rng = np.random.default_rng(1)
    values = {"load_inertia": rng.uniform(0.0, 4.0, n), "stiffness": rng.uniform(0.7, 1.3, n)}
    P0 = fill(builder.model, REF)
    P, T, tix = builder.rows(P0, values, lambda m: fill(m, REF))
    X0 = np.array([initial_state(builder.model, p) for p in P])
    sub = int(round(builder.model.sample_time / DT))
    return P, T, tix, X0, sub


def test_lanes_equal_the_per_variant_loop_with_variants_failing_mid_block(ema):
    scene, controller = ema
    n = 2 * W + 3  # two full blocks and a partial one
    P, T, tix, X0, sub = _rows(scene, controller, n)
    P[2, lo.KT] = np.nan  # non-finite from the first step, in the first block
    P[W + 3, lo.STROKE_HI] = X0[W + 3, 2] + math.radians(0.5)  # leaves the stroke mid-run
    P[2 * W + 1, lo.STROKE_LO] = X0[2 * W + 1, 2] - math.radians(0.3)  # in the partial block
    one, lanes = _both(P, T, tix, X0, sub)
    status = one[1][:, F_STATUS]
    assert status[2] == lo.NONFINITE and status[W + 3] == lo.STROKE_END and status[2 * W + 1] == lo.STROKE_END
    assert 0 < one[1][W + 3, F_STEP] < STEPS and 0 < one[1][2 * W + 1, F_STEP] < STEPS
    assert np.sum(status == lo.OK) == n - 3
    _assert_equal(one, lanes)
    # a block-mate of a stopped variant is the same as when it runs without it
    alone = _both(P[W + 4:W + 5], T, tix[W + 4:W + 5], X0[W + 4:W + 5], sub)[1]
    np.testing.assert_array_equal(alone[1][0], lanes[1][W + 4])


def test_a_block_with_a_rigid_variant_runs_variant_by_variant(ema):
    """The lanes leave out the rigid chain's branch: a block holding one variant flagged rigid
    runs variant by variant, its neighbour block in lanes, and both equal the per-variant
    loop (in lanes the variant would get the two-mass chain's law); a variant without an
    inductance (algebraic current) stays in lanes."""
    scene, controller = ema
    P, T, tix, X0, sub = _rows(scene, controller, 2 * W)
    P[1, lo.RIGID] = 1.0
    P[W + 1, lo.L] = 0.0
    assert not block_kind(P, 0, W)[0] and block_kind(P, W, W)[0]
    one, lanes = _both(P, T, tix, X0, sub, steps=400)
    assert not np.allclose(one[0][1], one[0][0], rtol=1e-3)  # the variants do differ
    assert not np.allclose(one[0][W + 1], one[0][W], rtol=1e-3)
    _assert_equal(one, lanes)


def test_lanes_with_own_tables_and_references(ema):
    """Variants with their own stroke tables (here a stiffness table 20 % up in every other
    variant) read their own in lanes; a block whose references differ evaluates each
    variant's own; a rigid chain's variants (their own inertia tables) run variant by
    variant."""
    scene, controller = ema
    P, T, tix, X0, sub = _rows(scene, controller, W + 2)
    stiffer = T[tix[0]].copy()
    stiffer[lo.T_K:lo.T_K + 2] *= 1.2
    T = np.concatenate([T, stiffer[None]])
    tix = np.where(np.arange(len(P)) % 2 == 1, len(T) - 1, tix)
    P[1, lo.REF_A] *= 0.5
    one, lanes = _both(P, T, tix, X0, sub)
    assert not np.allclose(one[0][3], one[0][2], rtol=1e-3)
    _assert_equal(one, lanes)
    rigid = ModelOptions(**{**sine_run_options(scene, controller, REF)[0].__dict__, "compliance": False})
    P, T, tix, X0, sub = _rows(scene, controller, 3, rigid)
    assert len(T) > 1 and len(set(tix)) > 1 and not block_kind(P, 0, 3)[0]
    _assert_equal(*_both(P, T, tix, X0, sub, steps=300))


def test_a_block_with_a_continuous_controller_runs_variant_by_variant(ema):
    scene, controller = ema
    model = build_model(scene, controller, ModelOptions(controller_mode="continuous"))
    P0 = fill(model, REF)
    assert P0[lo.CMODE] == lo.CONTINUOUS
    P = np.array([P0] * 3)
    P[1, lo.KSCALE] *= 1.2
    X0 = np.array([initial_state(model, p) for p in P])
    one, lanes = _both(P, model.T[None], np.zeros(3, dtype=np.int64), X0, 0, steps=300)
    for a, b in zip(one, lanes):
        np.testing.assert_array_equal(b, a)


@pytest.mark.parametrize("estimator", ["difference", "kalman"])
def test_lanes_with_a_speed_estimator_and_quantized_encoders(ema, estimator):
    """The sampled controller's measurements (encoder quantization, the speed estimator's own
    states) run lane by lane, its state-space update across the lanes: the figures and the
    estimator's states equal the per-variant loop."""
    scene, controller = ema
    options = ModelOptions(**{**sine_run_options(scene, controller, REF)[0].__dict__, "speed_estimator": estimator})
    P, T, tix, X0, sub = _rows(scene, controller, W + 3, options)
    assert P[0, lo.EST] > 0 and P[0, lo.LSB] > 0 and P[0, lo.LSB_M] > 0
    assert X0.shape[1] > lo.NX_PHYS + int(P[0, lo.NC])  # estimator states after the controller's
    _assert_equal(*_both(P, T, tix, X0, sub))


def _motion_pair():
    """Compile kernel._motion and kernel.motion_columns under the same flags (numba's
    defaults) for the comparison below."""
    import numba as nb

    from servo_toolkit.sim.kernel import _motion, motion_columns

    @nb.njit
    def one(x, P, r, th, wm, work):
        y = _motion(x, P, r, th, wm, work, 0, True)
        return y

    @nb.njit
    def cols(X, P, r, th, wm, y, xn):
        motion_columns(X, P, r, th, wm, y, xn, X.shape[1])

    return one, cols


@pytest.mark.parametrize("nc", [0, 1, 3, 5])
def test_motion_columns_equals_the_single_controller_update_bit_for_bit(nc):
    """kernel.motion_columns is kernel._motion (the sampled state-space step) with the lanes
    side by side: for random controllers, states and inputs, every column's output and next
    state equal _motion's to the last bit."""
    one, cols = _motion_pair()
    rng = np.random.default_rng(nc)
    w, nx = 6, lo.NX_PHYS + nc + 2  # two trailing states (an estimator's) the update ignores
    oa, ob, oc, od = 60, 60 + nc * nc, 60 + nc * nc + 3 * nc, 60 + nc * nc + 4 * nc
    P = rng.normal(size=(od + 3, w)) * np.logspace(-3, 3, od + 3)[:, None]
    P[lo.NC], P[lo.OFF_A], P[lo.OFF_B], P[lo.OFF_C], P[lo.OFF_D] = nc, oa, ob, oc, od
    X = rng.normal(size=(nx, w)) * 10.0
    r, th, wm = rng.normal(size=(3, w))
    y, xn = np.full(w, np.nan), np.full((max(nc, 1), w), np.nan)
    cols(X, P, r, th, wm, y, xn)
    for l in range(w):
        work = np.full(max(nc, 1), np.nan)
        y1 = one(X[:, l].copy(), P[:, l].copy(), r[l], th[l], wm[l], work)
        assert y[l] == y1
        np.testing.assert_array_equal(xn[:nc, l], work[:nc])


def test_a_block_of_controllers_of_different_structures_runs_variant_by_variant():
    from servo_toolkit.sim.batch_lanes import block_kind
    P = np.zeros((3, lo.NP_HEADER))  # every header slot (the kernels read them unchecked)
    P[:, lo.CMODE] = 1.0
    assert block_kind(P, 0, 3) == (True, True)
    P[1, lo.NC] = 2.0
    assert block_kind(P, 0, 3)[0] is False
    P[1, lo.NC] = 0.0
    P[2, lo.OFF_C] = 40.0
    assert block_kind(P, 0, 3)[0] is False
    assert block_kind(P, 0, 2) == (True, True)


@pytest.mark.parametrize("compliance", [True, False])
def test_lanes_with_friction_that_holds_equal_the_per_variant_loop(ema, compliance):
    """Friction that holds in the lanes: the stick and breakaway law branch-free, a lane whose
    node reverses its speed within a step split there as the single run splits it. Static
    friction on the motor (every variant, at its own level), on the load (some), one lane with
    the smooth model beside them: figures and states equal the per-variant loop, and the
    stick changes what the smooth model gives."""
    from servo_toolkit.sim.batch_lanes import block_kind
    scene, controller = ema
    options = ModelOptions(**{**sine_run_options(scene, controller, REF)[0].__dict__, "friction": "stick",
                              "compliance": compliance})
    P, T, tix, X0, sub = _rows(scene, controller, W + 3, options)
    assert np.all(P[:, lo.STICK] == 1.0)
    P[:, lo.TS_M] = np.linspace(0.03, 0.3, len(P))  # above the motor's Coulomb level, 0.02 N*m
    P[::2, lo.TC_L], P[::2, lo.TS_L], P[::2, lo.INV_VS_L] = 5.0, 8.0, 1.0 / 0.05
    P[3, lo.STICK] = 0.0  # the smooth model beside friction that holds, in one block
    assert block_kind(np.ascontiguousarray(P), 0, W) == (compliance, True)  # a rigid chain: variant by variant
    one, lanes = _both(P, T, tix, X0, sub)
    assert np.all(one[1][:, F_STATUS] == lo.OK)
    _assert_equal(one, lanes)
    smooth = P.copy()
    smooth[:, lo.STICK] = 0.0
    slid = _both(smooth, T, tix, X0, sub)[1]
    # friction that holds changes where the output ends (by 1e-7 to 1e-3 rad here), the
    # smooth lane not at all
    moved = np.abs(slid[0][:, 2] - lanes[0][:, 2])
    assert np.all(np.delete(moved, 3) > 1e-8) and moved[3] == 0.0


def test_open_loop_lanes_equal_the_per_variant_loop(ema):
    """Open loop (a constant voltage plus a sine swing): the lanes take each lane's command
    from outside their vectorized loop, the per-variant loop evaluates it in the right-hand
    side; the same runs, and a lane's own swing frequency reaches its lane."""
    from servo_toolkit.sim.batch_lanes import block_kind
    scene, _ = ema
    model = build_model(scene, None)
    ref = Reference.voltage(2.0, swing=3.0, frequency=40.0)
    P = np.array([fill(model, ref)] * (W + 2))
    assert P[0, lo.CMODE] == lo.OPEN_LOOP
    P[:, lo.KSCALE] = np.linspace(0.7, 1.3, len(P))
    P[1, lo.REF_F] = 25.0
    X0 = np.array([initial_state(model, p) for p in P])
    assert block_kind(np.ascontiguousarray(P), 0, W)[0]
    one, lanes = _both(P, model.T[None], np.zeros(len(P), dtype=np.int64), X0, 0, steps=600)
    assert np.all(one[1][:, F_STATUS] == lo.OK)
    _assert_equal(one, lanes)
    # the swing moves the motor: a lane without it ends elsewhere
    still = P.copy()
    still[:, lo.REF_A] = 0.0
    flat = _both(still, model.T[None], np.zeros(len(P), dtype=np.int64), X0, 0, steps=600)[1]
    assert np.all(np.abs(flat[0][:, 1] - lanes[0][:, 1]) > 1e-3)
    assert abs(lanes[0][1, 1] - lanes[0][0, 1]) > 1e-3
