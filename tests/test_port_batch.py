"""The C batch (servo_toolkit/_physics/batch.h: every variant through the single run's RK4 loop,
on threads) equals numba's per-variant loop (servo_toolkit.sim.batch.run_variants) and its SIMD
lanes (batch_lanes.run_lanes) on the variants the batch's tests build, the C Jacobians equal
numba's, the Monte Carlo study gives the same numbers with them, and threads change nothing.

Agreement: the numba loop was compiled with fast-math flags (contraction into fused
multiply-adds, reciprocals, reassociation), the lanes without contraction and reassociation,
and the right-hand side uses its own tanh and exp; the C loop rounds as IEEE double without
contraction. So the two differ in the last bits of a step, and the difference is carried
through the run's feedback: the figures (a peak over the run) agree to a relative 1e-12, as
the lanes agree with the per-variant loop (tests/test_batch_lanes.py), statuses, steps and
the limit flag exactly; the final state and snapshots to the lanes' tolerance there (rtol 1e-9:
a state that nearly cancels, such as a PI integral near zero, keeps the absolute rounding of
its terms), and a snapshot taken at the same step as numba's (all of them, here) to 1e-12 of
each state's full scale over the batch's snapshots; the peak-current snapshot's current equals
the peak. The Jacobians are central
differences with steps of 1e-7: a right-hand side's last-bit difference ``eps |f|`` becomes
``eps |f| / h``, so they agree to 1e-12 of each row's full scale over h (see
:func:`_jacobian_tolerance`). These comparison tests go with numba.
"""

from __future__ import annotations

import math
import tomllib
import time

import numpy as np
import pytest

from servo_toolkit._physics import _kernels as ck
from servo_toolkit.sim import ModelOptions, Reference, build_model
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.batch import (F_CUR, F_ERR, F_SAT, F_STATUS, F_STEP, F_TAU, NFIG, NSNAP, S_DEFLECTION,
                                     S_END, S_PEAK, run_variants as nb_run_variants)
from servo_toolkit.sim.batch_lanes import W, run_lanes
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.tables import frozen_tables
from servo_toolkit.studies.time_run import sine_run_options

from .conftest import SCENES, build, variant
from .test_batch_lanes import DT, REF, STEPS, _rows


# ---------------------------------------------------------------------------------------------
# the variants of tests/test_batch_lanes.py


def _mid_block_failures(scene, controller):
    P, T, tix, X0, sub = _rows(scene, controller, 2 * W + 3)
    P[2, lo.KT] = np.nan
    P[W + 3, lo.STROKE_HI] = X0[W + 3, 2] + math.radians(0.5)
    P[2 * W + 1, lo.STROKE_LO] = X0[2 * W + 1, 2] - math.radians(0.3)
    return P, T, tix, X0, sub, STEPS


def _rigid_flag(scene, controller):
    P, T, tix, X0, sub = _rows(scene, controller, 2 * W)
    P[1, lo.RIGID] = 1.0
    P[W + 1, lo.L] = 0.0
    return P, T, tix, X0, sub, 400


def _own_tables(scene, controller):
    P, T, tix, X0, sub = _rows(scene, controller, W + 2)
    stiffer = T[tix[0]].copy()
    stiffer[lo.T_K:lo.T_K + 2] *= 1.2
    T = np.concatenate([T, stiffer[None]])
    tix = np.where(np.arange(len(P)) % 2 == 1, len(T) - 1, tix)
    P[1, lo.REF_A] *= 0.5
    return P, T, tix, X0, sub, STEPS


def _options(scene, controller, **edits):
    return ModelOptions(**{**sine_run_options(scene, controller, REF)[0].__dict__, **edits})


def _rigid_chain(scene, controller):
    return (*_rows(scene, controller, 3, _options(scene, controller, compliance=False)), 300)


def _continuous(scene, controller):
    model = build_model(scene, controller, ModelOptions(controller_mode="continuous"))
    P = np.array([fill(model, REF)] * 3)
    P[1, lo.KSCALE] *= 1.2
    X0 = np.array([initial_state(model, p) for p in P])
    return P, model.T[None], np.zeros(3, dtype=np.int64), X0, 0, 300


def _estimator(kind):
    def case(scene, controller):
        return (*_rows(scene, controller, W + 3, _options(scene, controller, speed_estimator=kind)), STEPS)
    return case


def _stick(compliance):
    def case(scene, controller):
        P, T, tix, X0, sub = _rows(scene, controller, W + 3,
                                   _options(scene, controller, friction="stick", compliance=compliance))
        P[:, lo.TS_M] = np.linspace(0.03, 0.3, len(P))
        P[::2, lo.TC_L], P[::2, lo.TS_L], P[::2, lo.INV_VS_L] = 5.0, 8.0, 1.0 / 0.05
        P[3, lo.STICK] = 0.0
        return P, T, tix, X0, sub, STEPS
    return case


def _open_loop(scene, controller):
    model = build_model(scene, None)
    P = np.array([fill(model, Reference.voltage(2.0, swing=3.0, frequency=40.0))] * (W + 2))
    P[:, lo.KSCALE] = np.linspace(0.7, 1.3, len(P))
    P[1, lo.REF_F] = 25.0
    X0 = np.array([initial_state(model, p) for p in P])
    return P, model.T[None], np.zeros(len(P), dtype=np.int64), X0, 0, 600


def _cam_chain(scene, controller):
    """A chain ending in a cam (the follower's weight and guide friction through cam.h's
    shaft_acceleration), open loop at a constant voltage, variants of the guide friction's
    smoothing and the motor's constant."""
    cam = build(variant(tomllib.loads((SCENES / "cam_follower.toml").read_text()),
                        drivetrain__0__gravity_tilt="30 deg", drivetrain__0__guide_friction_coefficient=0.2))
    model = build_model(cam, None)
    P = np.array([fill(model, Reference.voltage(3.5))] * 5)
    assert P[0, lo.CAM] > 0
    P[:, lo.KT] *= np.linspace(0.8, 1.2, len(P))
    X0 = np.array([initial_state(model, p) for p in P])
    return P, model.T[None], np.zeros(len(P), dtype=np.int64), X0, 0, 2000


CASES = {
    "variants failing mid-block": _mid_block_failures,
    "a rigid flag and no inductance": _rigid_flag,
    "own tables and references": _own_tables,
    "rigid chain, own inertia tables": _rigid_chain,
    "continuous controller": _continuous,
    "difference speed estimator": _estimator("difference"),
    "kalman speed estimator": _estimator("kalman"),
    "friction that holds, compliant": _stick(True),
    "friction that holds, rigid": _stick(False),
    "open loop": _open_loop,
    "cam chain": _cam_chain,
}


@pytest.fixture(scope="module")
def cases(ema):
    scene, controller = ema
    return {name: make(scene, controller) for name, make in CASES.items()}


def _run(fn, P, T, tix, X0, sub, steps, **kw):
    X = np.array(X0, dtype=float)
    figs = np.zeros((len(X), NFIG))
    snaps = np.zeros((len(X), NSNAP, X.shape[1] + 2))
    fn(X, np.ascontiguousarray(P), frozen_tables(T), np.ascontiguousarray(tix, dtype=np.int64), DT, steps, sub,
       figs, snaps, **kw)
    return X, figs, snaps


def _compare(c, ref, what):
    """Largest relative differences of the C run ``c`` against ``ref`` (numba); asserts the
    agreement the module's docstring states."""
    (X1, f1, s1), (X2, f2, s2) = ref, c
    np.testing.assert_array_equal(f2[:, F_STATUS], f1[:, F_STATUS], err_msg=what)
    np.testing.assert_array_equal(f2[:, F_STEP], f1[:, F_STEP], err_msg=what)
    np.testing.assert_array_equal(f2[:, F_SAT], f1[:, F_SAT], err_msg=what)
    for col in (F_ERR, F_CUR, F_TAU):
        np.testing.assert_allclose(f2[:, col], f1[:, col], rtol=1e-12, atol=1e-14, err_msg=what)
    np.testing.assert_allclose(X2, X1, rtol=1e-9, atol=1e-12, err_msg=what)
    np.testing.assert_allclose(s2[:, S_END], s1[:, S_END], rtol=1e-9, atol=1e-12, err_msg=what)
    np.testing.assert_allclose(np.abs(s2[:, S_PEAK, 4]), f2[:, F_CUR], rtol=1e-12, err_msg=what)
    np.testing.assert_allclose(np.abs(s1[:, S_PEAK, 4]), f2[:, F_CUR], rtol=1e-12, err_msg=what)

    def rel(a, b):
        ok = np.isfinite(a) & np.isfinite(b)
        scale = np.maximum(np.abs(b), 1e-300)
        return float(np.max(np.abs(a - b)[ok] / scale[ok], initial=0.0))

    figs_rel = max(rel(f2[:, col], f1[:, col]) for col in (F_ERR, F_CUR, F_TAU))
    # snapshots: the same state where the same step was taken (its time equal), each state
    # against its full scale over the batch's snapshots (a speed through zero has no digits
    # of its own)
    nx = X1.shape[1]
    same_step = (s2[:, :, nx] == s1[:, :, nx]) & np.all(np.isfinite(s1), axis=2) & np.all(np.isfinite(s2), axis=2)
    a, b = s2[same_step], s1[same_step]
    full = np.maximum(np.max(np.abs(b), axis=0, initial=0.0), 1e-300)
    snap_rel = float(np.max(np.abs(a - b) / full, initial=0.0))
    assert snap_rel <= 1e-12, (what, snap_rel)
    return figs_rel, snap_rel, float(np.mean(same_step))


@pytest.mark.parametrize("name", list(CASES))
def test_c_batch_equals_the_numba_loop_and_lanes(cases, name):
    P, T, tix, X0, sub, steps = cases[name]
    c = _run(ck.run_variants, P, T, tix, X0, sub, steps)
    one = _run(nb_run_variants, P, T, tix, X0, sub, steps)
    lanes = _run(run_lanes, P, T, tix, X0, sub, steps)
    r1 = _compare(c, one, f"{name}: C against numba's per-variant loop")
    r2 = _compare(c, lanes, f"{name}: C against numba's lanes")
    print(f"\n{name}: figures rel {r1[0]:.1e} / {r2[0]:.1e} (loop / lanes), snapshots at the same step "
          f"{r1[1]:.1e} / {r2[1]:.1e} ({100 * r1[2]:.0f} % / {100 * r2[2]:.0f} % at the same step)")
    # every variant's own: variant_run on each row alone gives the batch's numbers to the bit
    X, figs, snaps = c
    for v in range(len(P)):
        x = np.array(X0[v], dtype=float)
        fig, snap = np.zeros(NFIG), np.zeros((NSNAP, x.size + 2))
        ck.variant_run(x, np.ascontiguousarray(P[v]), np.ascontiguousarray(T[tix[v]]), DT, steps, sub, fig, snap)
        np.testing.assert_array_equal(fig, figs[v])
        np.testing.assert_array_equal(snap, snaps[v])
        np.testing.assert_array_equal(x, X[v])


def test_the_statuses_are_reached(cases):
    f = _run(ck.run_variants, *cases["variants failing mid-block"])[1]
    status = f[:, F_STATUS]
    assert status[2] == lo.NONFINITE and status[W + 3] == lo.STROKE_END and status[2 * W + 1] == lo.STROKE_END
    assert 0 < f[W + 3, F_STEP] < STEPS and np.sum(status == lo.OK) == len(f) - 3


@pytest.mark.parametrize("name", ["variants failing mid-block", "friction that holds, compliant", "cam chain"])
def test_threads_give_the_numbers_of_one_thread(cases, name):
    P, T, tix, X0, sub, steps = cases[name]
    one = _run(ck.run_variants, P, T, tix, X0, sub, steps, threads=1)
    for threads in (2, 3, 64):
        many = _run(ck.run_variants, P, T, tix, X0, sub, steps, threads=threads)
        for a, b in zip(many, one):
            np.testing.assert_array_equal(a, b)


def test_bad_arguments_are_refused(cases):
    P, T, tix, X0, sub, steps = cases["own tables and references"]
    X = np.array(X0, dtype=float)
    figs, snaps = np.zeros((len(X), NFIG)), np.zeros((len(X), NSNAP, X.shape[1] + 2))
    with pytest.raises(ValueError, match="table index"):
        ck.run_variants(X, P, T, np.full(len(P), len(T)), DT, 10, sub, figs, snaps)
    with pytest.raises(ValueError, match="snaps"):
        ck.run_variants(X, P, T, tix, DT, 10, sub, figs, snaps[:, :, :-1].copy())
    with pytest.raises(ValueError, match="X"):
        ck.run_variants(X[:, ::2], P, T, tix, DT, 10, sub, figs, snaps)
    empty = np.zeros((0, X.shape[1]))
    ck.run_variants(empty, P[:0], T, tix[:0], DT, 10, sub, np.zeros((0, NFIG)), np.zeros((0, NSNAP, X.shape[1] + 2)))


# ---------------------------------------------------------------------------------------------
# the Jacobians


def _jacobian_tolerance(X, times, irefs, P, T, tix, vix):
    """1e-12 of each right-hand side's full scale over the step, per row k and column j:
    the rounding of f (last bits, scaled by its terms' magnitudes) divided by 2 h_j."""
    from servo_toolkit.sim.kernel import rhs
    m, n = X.shape
    scale = np.zeros((m, n))
    f, aux = np.empty(n), np.empty(lo.NAUX)
    for i in range(m):
        v = vix[i]
        rhs(times[i], X[i].copy(), P[v], T[tix[v]], irefs[i], f, aux)
        scale[i] = np.abs(f)
    full = np.max(scale, axis=0)  # per state's slope, over the rows
    h = 1e-7 * (1.0 + np.abs(X))
    return 1e-12 * np.maximum(scale, full)[:, :, None] / h[:, None, :]


@pytest.mark.parametrize("name", ["own tables and references", "friction that holds, compliant",
                                  "rigid chain, own inertia tables", "kalman speed estimator", "cam chain"])
def test_jacobians_equal_numba(cases, name):
    from servo_toolkit.sim.batch import jacobians as nb_jacobians
    P, T, tix, X0, sub, steps = cases[name]
    X, figs, snaps = _run(ck.run_variants, P, T, tix, X0, sub, steps)
    ok = figs[:, F_STATUS] == lo.OK
    nx = X.shape[1]
    rows = snaps[ok].reshape(-1, nx + 2)  # every snapshot of every variant that ran through
    vix = np.repeat(np.flatnonzero(ok), NSNAP).astype(np.int64)
    XS, times, irefs = np.ascontiguousarray(rows[:, :nx]), rows[:, nx].copy(), rows[:, nx + 1].copy()
    T = frozen_tables(T)
    tix = np.ascontiguousarray(tix, dtype=np.int64)
    Jc, Jn = np.empty((len(XS), nx, nx)), np.empty((len(XS), nx, nx))
    ck.jacobians(XS, times, irefs, P, T, tix, vix, Jc)
    nb_jacobians(XS, times, irefs, np.ascontiguousarray(P), T, tix, vix, Jn)
    tol = _jacobian_tolerance(XS, times, irefs, np.ascontiguousarray(P), T, tix, vix)
    diff = np.abs(Jc - Jn)
    assert np.all(diff <= tol), float(np.max(diff / np.maximum(tol, 1e-300)))
    exact = np.mean(Jc == Jn)
    print(f"\n{name}: {len(XS)} Jacobians, {100 * exact:.0f} % of entries equal to the bit, largest difference "
          f"{float(np.max(diff / np.maximum(tol, 1e-300))):.2g} of the tolerance")


# ---------------------------------------------------------------------------------------------
# the Monte Carlo study with the C batch in batch_run's place


def c_integrate_variants(P, T, tix, X0, dt, n_steps, sub, threads=2):
    """What servo_toolkit.sim.batch_run.integrate_variants becomes with the C batch: calls of
    about CHUNK_S each (Ctrl-C between two), every variant on ``threads`` threads."""
    from servo_toolkit.sim.integrators import CHUNK_S
    P = np.ascontiguousarray(P, dtype=float)
    T = np.ascontiguousarray(T, dtype=float)
    tix = np.ascontiguousarray(tix, dtype=np.int64)
    X = np.array(X0, dtype=float, order="C")
    nv, nx = X.shape
    figs = np.zeros((nv, NFIG))
    snaps = np.zeros((nv, NSNAP, nx + 2))
    start = time.perf_counter()
    v, size = 0, threads
    while v < nv:
        end = min(nv, v + size)
        began = time.perf_counter()
        ck.run_variants(X[v:end], P[v:end], T, tix[v:end], dt, int(n_steps), int(sub), figs[v:end], snaps[v:end],
                        threads)
        per_variant = max(time.perf_counter() - began, 1e-9) / (end - v)
        size = max(threads, min(10 * (end - v), int(CHUNK_S * threads / per_variant)))
        v = end
    return X, figs, snaps, time.perf_counter() - start


def _mc_arrays(mc):
    return {k: np.asarray(getattr(mc, k), dtype=float) for k in ("tracking_error", "peak_current")}


@pytest.mark.parametrize("kw", [{"variants": {"load_inertia": (0.0, 4.0), "stiffness": (0.7, 1.3)}, "samples": 12},
                                {"variants": {"stiffness": np.array([0.8, 1e6, 1.2])}},
                                {"variants": {"load_inertia": (0.5, 3.0)}, "samples": 4, "feedforward": "model"},
                                {"variants": {"load_inertia": (0.5, 3.0)}, "samples": 4, "full": True}],
                         ids=["load and stiffness", "one failing", "feedforward", "full chain"])
def test_montecarlo_with_the_c_batch(ema, monkeypatch, kw):
    import servo_toolkit.studies.montecarlo as mc_mod
    import servo_toolkit.studies.variant_step as vs_mod
    from servo_toolkit.studies.montecarlo import montecarlo
    scene, controller = ema
    kw = dict(kw)
    variants = kw.pop("variants")

    def go():
        return montecarlo(scene, variants, controller=controller, duration=0.1, progress=False, seed=1, **kw)

    ref = go()
    calls = []

    def counted(fn):
        def call(*args, **kwargs):
            calls.append(fn)
            return fn(*args, **kwargs)
        return call

    monkeypatch.setattr(mc_mod, "integrate_variants", counted(c_integrate_variants))
    monkeypatch.setattr(vs_mod, "jacobians", counted(ck.jacobians))
    c = go()
    assert c_integrate_variants in calls and ck.jacobians in calls
    assert list(c.failed) == list(ref.failed) and list(c.reasons) == list(ref.reasons)
    for k, a in _mc_arrays(c).items():
        np.testing.assert_allclose(a, _mc_arrays(ref)[k], rtol=1e-12, err_msg=k)


# ---------------------------------------------------------------------------------------------
# time (printed, not asserted)


def test_wall_time_per_variant(cases):
    """Wall time per variant: numba's single run of a variant (its per-variant loop), numba's
    lanes (on numba's threads), the C batch on 1 and 2 threads."""
    import numba as nb
    P, T, tix, X0, sub, _ = cases["own tables and references"]
    P = np.repeat(P, 4, axis=0)
    X0 = np.repeat(X0, 4, axis=0)
    tix = np.repeat(tix, 4)
    steps = 5000
    rows = []
    for label, fn, kw in [("numba per-variant loop (one single run each)", nb_run_variants, {}),
                          (f"numba lanes ({nb.get_num_threads()} threads)", run_lanes, {}),
                          ("C batch, 1 thread", ck.run_variants, {"threads": 1}),
                          ("C batch, 2 threads", ck.run_variants, {"threads": 2})]:
        _run(fn, P[:1], T, tix[:1], X0[:1], sub, 10, **kw)  # loaded
        best = math.inf
        for _ in range(3):
            began = time.perf_counter()
            _run(fn, P, T, tix, X0, sub, steps, **kw)
            best = min(best, time.perf_counter() - began)
        rows.append(f"  {label:48s} {1e3 * best / len(P):7.2f} ms per variant ({steps} steps)")
    print("\n" + "\n".join(rows))
