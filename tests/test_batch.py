"""The compiled batch (:func:`servo_toolkit.sim.batch.run_variants`: every variant through the
single run's RK4 loop, on worker threads) gives every variant the numbers of its single run
(:func:`~servo_toolkit.sim.batch.variant_run` on its row alone, and
:func:`servo_toolkit.sim.run`) and of one thread, to the bit: with variants that stop
mid-run (non-finite, stroke end) beside others that go on, variants with their own tables and
references, a rigid chain, a continuous controller, speed estimators, friction that holds, the
full chain, open loop and a cam. Bad arguments are refused, and the batch's Jacobians are the
central differences of the right-hand side."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from servo_toolkit.sim import ModelOptions, Reference, build_model, run
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.batch import (F_CUR, F_ERR, F_STATUS, F_STEP, F_TAU, NFIG, NSNAP, S_PEAK, jacobians,
                                     run_variants, variant_run)
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.tables import frozen_tables
from servo_toolkit.sim.variants import VariantBuilder
from servo_toolkit.studies.time.run import sine_run_options

from .conftest import SCENES, build, variant
from .jacobian_reference import central_differences

REF = Reference.sine(math.radians(2.0), 8.0)
DT = 1e-4
STEPS = 1500


def batch(P, T, tix, X0, sub, steps=STEPS, threads=1, dt=DT):
    """``(X, figs, snaps)`` of one :func:`run_variants` call from the starts ``X0``."""
    X = np.array(X0, dtype=float)
    figs = np.zeros((len(X), NFIG))
    snaps = np.zeros((len(X), NSNAP, X.shape[1] + 2))
    run_variants(X, np.ascontiguousarray(P), frozen_tables(T), np.ascontiguousarray(tix, dtype=np.int64), dt,
                 steps, sub, figs, snaps, threads)
    return X, figs, snaps


def singles(P, T, tix, X0, sub, steps=STEPS, dt=DT):
    """``(X, figs, snaps)`` of :func:`variant_run` on every row alone."""
    X = np.array(X0, dtype=float)
    figs = np.zeros((len(X), NFIG))
    snaps = np.zeros((len(X), NSNAP, X.shape[1] + 2))
    for v in range(len(X)):
        x, fig, snap = X[v].copy(), np.zeros(NFIG), np.zeros((NSNAP, X.shape[1] + 2))
        variant_run(x, np.ascontiguousarray(P[v]), np.ascontiguousarray(T[tix[v]]), dt, steps, sub, fig, snap)
        X[v], figs[v], snaps[v] = x, fig, snap
    return X, figs, snaps


def assert_same(got, want, what=""):
    """Every state, figure and snapshot equal to the bit (NaN where NaN)."""
    for name, a, b in zip(("X", "figs", "snaps"), got, want):
        assert np.array_equal(a, b, equal_nan=True), f"{what}: {name}"


def assert_as_single_runs(P, T, tix, X0, sub, steps=STEPS, dt=DT, threads=(1, 2, 3)):
    """The batch on each of ``threads`` equals every variant's single run; returns the run."""
    alone = singles(P, T, tix, X0, sub, steps, dt)
    for n in threads:
        assert_same(batch(P, T, tix, X0, sub, steps, threads=n, dt=dt), alone, f"{n} threads")
    return alone


def _rows(scene, controller, n, options=None, dt=DT):
    options = options or sine_run_options(scene, controller, REF)[0]
    builder = VariantBuilder.create(scene, controller, options)
    rng = np.random.default_rng(1)
    values = {"load_inertia": rng.uniform(0.0, 4.0, n), "stiffness": rng.uniform(0.7, 1.3, n)}
    P0 = fill(builder.model, REF)
    P, T, tix = builder.rows(P0, values, lambda m: fill(m, REF))
    X0 = np.array([initial_state(builder.model, p) for p in P])
    sub = int(round(builder.model.sample_time / dt))
    return P, T, tix, X0, sub


def _options(scene, controller, **edits):
    return ModelOptions(**{**sine_run_options(scene, controller, REF)[0].__dict__, **edits})


# ---------------------------------------------------------------------------------------------
# the variant sets


N_FAIL, STOPS = 11, (2, 7, 9)  # the variants stopped: non-finite, stroke end above, below


def _failing_mid_run(scene, controller):
    P, T, tix, X0, sub = _rows(scene, controller, N_FAIL)
    nan, hi, lo_ = STOPS
    P[nan, lo.KT] = np.nan  # non-finite from the first step
    P[hi, lo.STROKE_HI] = X0[hi, 2] + math.radians(0.5)  # leaves the stroke mid-run
    P[lo_, lo.STROKE_LO] = X0[lo_, 2] - math.radians(0.3)
    return P, T, tix, X0, sub, STEPS


def _rigid_flag(scene, controller):
    P, T, tix, X0, sub = _rows(scene, controller, 6)
    P[1, lo.RIGID] = 1.0
    P[4, lo.L] = 0.0  # no inductance: an algebraic current
    return P, T, tix, X0, sub, 400


def _own_tables(scene, controller):
    """A stiffness table 20 % up in every other variant, one variant's own reference."""
    P, T, tix, X0, sub = _rows(scene, controller, 6)
    stiffer = T[tix[0]].copy()
    stiffer[lo.T_K:lo.T_K + 2] *= 1.2
    T = np.concatenate([T, stiffer[None]])
    tix = np.where(np.arange(len(P)) % 2 == 1, len(T) - 1, tix)
    P[1, lo.REF_A] *= 0.5
    return P, T, tix, X0, sub, STEPS


def _rigid_chain(scene, controller):
    """A rigid chain whose load inertia varies: every variant its own inertia tables."""
    return (*_rows(scene, controller, 3, _options(scene, controller, compliance=False)), 300)


def _continuous(scene, controller):
    model = build_model(scene, controller, ModelOptions(controller_mode="continuous"))
    P = np.array([fill(model, REF)] * 3)
    assert P[0, lo.CMODE] == lo.CONTINUOUS
    P[1, lo.KSCALE] *= 1.2
    X0 = np.array([initial_state(model, p) for p in P])
    return P, model.T[None], np.zeros(3, dtype=np.int64), X0, 0, 300


def _estimator(kind):
    """The sampled controller's measurements: quantized encoders and a speed estimator's own
    states after the controller's."""
    def case(scene, controller):
        P, T, tix, X0, sub = _rows(scene, controller, 5, _options(scene, controller, speed_estimator=kind))
        assert P[0, lo.EST] > 0 and P[0, lo.LSB] > 0 and P[0, lo.LSB_M] > 0
        assert X0.shape[1] > lo.NX_PHYS + int(P[0, lo.NC])
        return P, T, tix, X0, sub, STEPS
    return case


def _stick(compliance, chain=None):
    """Friction that holds: static friction on the motor (every variant, at its own level,
    above its Coulomb level of 0.02 N*m), on the load (every other), one variant with the
    smooth model beside them. The full chain's stiff nodes take a step of 5 us."""
    def case(scene, controller):
        edits, dt = ({"chain": chain}, 5e-6) if chain else ({}, DT)
        P, T, tix, X0, sub = _rows(scene, controller, 7, _options(scene, controller, friction="stick",
                                                                  compliance=compliance, **edits), dt)
        assert np.all(P[:, lo.STICK] == 1.0)
        P[:, lo.TS_M] = np.linspace(0.03, 0.3, len(P))
        P[::2, lo.TC_L], P[::2, lo.TS_L], P[::2, lo.INV_VS_L] = 5.0, 8.0, 1.0 / 0.05
        P[3, lo.STICK] = 0.0
        return P, T, tix, X0, sub, STEPS, dt
    return case


def _open_loop(scene, controller):
    """A constant voltage plus a sine swing, one variant's swing at its own frequency."""
    model = build_model(scene, None)
    P = np.array([fill(model, Reference.voltage(2.0, swing=3.0, frequency=40.0))] * 6)
    assert P[0, lo.CMODE] == lo.OPEN_LOOP
    P[:, lo.KSCALE] = np.linspace(0.7, 1.3, len(P))
    P[1, lo.REF_F] = 25.0
    X0 = np.array([initial_state(model, p) for p in P])
    return P, model.T[None], np.zeros(len(P), dtype=np.int64), X0, 0, 600


def _cam_chain(scene, controller):
    """A chain ending in a cam (the follower's weight and guide friction), open loop at a
    constant voltage, variants of the motor's constant."""
    cam = build(variant(tomllib.loads((SCENES / "cam_follower.toml").read_text()),
                        drivetrain__0__gravity_tilt="30 deg", drivetrain__0__guide_friction_coefficient=0.2))
    model = build_model(cam, None)
    P = np.array([fill(model, Reference.voltage(3.5))] * 5)
    assert P[0, lo.CAM] > 0
    P[:, lo.KT] *= np.linspace(0.8, 1.2, len(P))
    X0 = np.array([initial_state(model, p) for p in P])
    return P, model.T[None], np.zeros(len(P), dtype=np.int64), X0, 0, 2000


CASES = {
    "variants failing mid-run": _failing_mid_run,
    "a rigid flag and no inductance": _rigid_flag,
    "own tables and references": _own_tables,
    "rigid chain, own inertia tables": _rigid_chain,
    "continuous controller": _continuous,
    "difference speed estimator": _estimator("difference"),
    "kalman speed estimator": _estimator("kalman"),
    "friction that holds, compliant": _stick(True),
    "friction that holds, rigid": _stick(False),
    "friction that holds, full chain": _stick(True, "full"),
    "open loop": _open_loop,
    "cam chain": _cam_chain,
}


@pytest.fixture(scope="module")
def cases(ema):
    scene, controller = ema
    made = {name: make(scene, controller) for name, make in CASES.items()}
    return {name: case if len(case) == 7 else (*case, DT) for name, case in made.items()}  # + the step


# ---------------------------------------------------------------------------------------------
# the batch is the single runs


@pytest.mark.parametrize("name", list(CASES))
def test_the_batch_on_one_and_more_threads_is_every_variant_s_single_run(cases, name):
    P, T, tix, X0, sub, steps, dt = cases[name]
    X, figs, snaps = assert_as_single_runs(P, T, tix, X0, sub, steps, dt)
    assert np.all(np.isfinite(figs[:, F_STEP]))
    ok = figs[:, F_STATUS] == lo.OK
    # the peak-current snapshot holds that peak
    np.testing.assert_array_equal(np.abs(snaps[ok, S_PEAK, 4]), figs[ok, F_CUR])


def test_variants_stopped_mid_run_leave_the_others_as_they_run_alone(cases):
    P, T, tix, X0, sub, steps, dt = cases["variants failing mid-run"]
    X, figs, snaps = batch(P, T, tix, X0, sub, steps, threads=2, dt=dt)
    status = figs[:, F_STATUS]
    nan, hi, lo_ = STOPS
    assert status[nan] == lo.NONFINITE and status[hi] == lo.STROKE_END and status[lo_] == lo.STROKE_END
    assert 0 < figs[hi, F_STEP] < steps and 0 < figs[lo_, F_STEP] < steps
    assert np.sum(status == lo.OK) == len(P) - 3
    assert np.all(figs[status == lo.OK, F_STEP] == steps)
    # a neighbour of a stopped variant is the same as in a batch of its own
    v = hi + 1
    assert_same(batch(P[v:v + 1], T, tix[v:v + 1], X0[v:v + 1], sub, steps, dt=dt),
                (X[v:v + 1], figs[v:v + 1], snaps[v:v + 1]))


def test_the_variants_differ(cases):
    """The variant sets are not the same run repeated: the rigid flag, the missing inductance,
    the stiffer tables and the halved reference each move the end state."""
    P, T, tix, X0, sub, steps, dt = cases["a rigid flag and no inductance"]
    X = batch(P, T, tix, X0, sub, steps, dt=dt)[0]
    assert not np.allclose(X[1], X[0], rtol=1e-3) and not np.allclose(X[4], X[3], rtol=1e-3)
    P, T, tix, X0, sub, steps, dt = cases["own tables and references"]
    X = batch(P, T, tix, X0, sub, steps, dt=dt)[0]
    assert not np.allclose(X[3], X[2], rtol=1e-3)
    P, T, tix, X0, sub, steps, dt = cases["rigid chain, own inertia tables"]
    assert len(T) > 1 and len(set(tix)) > 1


@pytest.mark.parametrize("name", ["friction that holds, compliant", "friction that holds, rigid",
                                  "friction that holds, full chain"])
def test_friction_that_holds_changes_the_run_and_the_smooth_variant_not(cases, name):
    """Friction that holds moves where the output ends (by 1e-7 to 1e-3 rad here); the variant
    with the smooth model beside them not at all."""
    P, T, tix, X0, sub, steps, dt = cases[name]
    held = batch(P, T, tix, X0, sub, steps, threads=2, dt=dt)
    assert np.all(held[1][:, F_STATUS] == lo.OK)
    smooth = P.copy()
    smooth[:, lo.STICK] = 0.0
    slid = batch(smooth, T, tix, X0, sub, steps, threads=2, dt=dt)
    moved = np.abs(slid[0][:, 2] - held[0][:, 2])
    assert np.all(np.delete(moved, 3) > 1e-8) and moved[3] == 0.0


def test_an_open_loop_variant_runs_its_own_swing(cases):
    P, T, tix, X0, sub, steps, dt = cases["open loop"]
    X, figs, _ = batch(P, T, tix, X0, sub, steps, threads=2, dt=dt)
    assert np.all(figs[:, F_STATUS] == lo.OK)
    still = P.copy()
    still[:, lo.REF_A] = 0.0
    flat = batch(still, T, tix, X0, sub, steps, threads=2, dt=dt)[0]
    assert np.all(np.abs(flat[:, 1] - X[:, 1]) > 1e-3)  # the swing moves the motor
    assert abs(X[1, 1] - X[0, 1]) > 1e-3  # at its own frequency


@pytest.mark.parametrize("options, dt", [({}, DT), ({"friction": "stick"}, DT),
                                         ({"chain": "full", "friction": "stick"}, 5e-6)],
                         ids=["default", "friction that holds", "full chain"])
def test_a_variant_ends_where_its_simulation_ends(ema, options, dt):
    """A variant of the batch is :func:`servo_toolkit.sim.run` at the same step: the same steps
    through the same compiled loop (the batch calls the single run's, not a copy of it), so its
    end state and peaks are the run's to the last bit."""
    scene, controller = ema
    model = build_model(scene, controller, ModelOptions(**options))
    P = np.array([fill(model, REF)] * 3)
    P[1, lo.KSCALE] *= 1.1
    P[2, lo.KSCALE] *= 0.9
    X0 = np.array([initial_state(model, p) for p in P])
    sub = int(round(model.sample_time / dt))
    X, figs, _ = batch(P, model.T[None], np.zeros(3, dtype=np.int64), X0, sub, STEPS, threads=2, dt=dt)
    assert np.all(figs[:, F_STATUS] == lo.OK) and np.all(figs[:, F_STEP] == STEPS)
    res = run(model, REF, STEPS * dt, method="rk4", dt=dt, output_dt=10 * dt, x0=X0[0], check_stability=False)
    assert res.dt_s == dt and res.steps == STEPS and res.times[-1] == pytest.approx(STEPS * dt, rel=1e-12)
    np.testing.assert_array_equal(res.states[-1], X[0])
    assert res.peaks["max_abs_current_A"] == figs[0, F_CUR]
    assert res.peaks["max_abs_tracking_error"] == figs[0, F_ERR]
    assert res.max_abs_motor_torque == figs[0, F_TAU]
    assert not np.allclose(X[1], X[0], rtol=1e-6) and not np.allclose(X[2], X[0], rtol=1e-6)


# ---------------------------------------------------------------------------------------------
# arguments


def test_bad_arguments_are_refused(cases):
    P, T, tix, X0, sub, steps, dt = cases["own tables and references"]
    X = np.array(X0, dtype=float)
    figs, snaps = np.zeros((len(X), NFIG)), np.zeros((len(X), NSNAP, X.shape[1] + 2))
    with pytest.raises(ValueError, match="table index"):
        run_variants(X, P, T, np.full(len(P), len(T)), DT, 10, sub, figs, snaps)
    with pytest.raises(ValueError, match="snaps"):
        run_variants(X, P, T, tix, DT, 10, sub, figs, snaps[:, :, :-1].copy())
    with pytest.raises(ValueError, match="X"):
        run_variants(X[:, ::2], P, T, tix, DT, 10, sub, figs, snaps)
    with pytest.raises(ValueError, match="figs"):
        run_variants(X, P, T, tix, DT, 10, sub, figs.astype(np.float32), snaps)
    with pytest.raises(ValueError, match="P must be"):
        run_variants(X, P[:-1], T, tix, DT, 10, sub, figs, snaps)
    with pytest.raises(ValueError, match="n_steps"):
        run_variants(X, P, T, tix, DT, -1, sub, figs, snaps)
    assert np.array_equal(X, X0) and not figs.any() and not snaps.any()  # nothing ran
    empty = np.zeros((0, X.shape[1]))
    run_variants(empty, P[:0], T, tix[:0], DT, 10, sub, np.zeros((0, NFIG)), np.zeros((0, NSNAP, X.shape[1] + 2)))


def test_more_threads_than_variants_give_the_numbers_of_one_thread(cases):
    P, T, tix, X0, sub, steps, dt = cases["friction that holds, compliant"]
    assert_same(batch(P, T, tix, X0, sub, steps, threads=64, dt=dt),
                batch(P, T, tix, X0, sub, steps, threads=1, dt=dt))


# ---------------------------------------------------------------------------------------------
# the Jacobians


@pytest.mark.parametrize("name", ["own tables and references", "friction that holds, compliant",
                                  "rigid chain, own inertia tables", "kalman speed estimator", "cam chain"])
def test_the_jacobians_are_the_central_differences_of_the_right_hand_side(cases, name):
    P, T, tix, X0, sub, steps, dt = cases[name]
    X, figs, snaps = batch(P, T, tix, X0, sub, steps, dt=dt)
    ok = figs[:, F_STATUS] == lo.OK
    nx = X.shape[1]
    rows = snaps[ok].reshape(-1, nx + 2)  # every snapshot of every variant that ran through
    vix = np.repeat(np.flatnonzero(ok), NSNAP).astype(np.int64)
    XS, times, irefs = np.ascontiguousarray(rows[:, :nx]), rows[:, nx].copy(), rows[:, nx + 1].copy()
    P, T, tix = np.ascontiguousarray(P), frozen_tables(T), np.ascontiguousarray(tix, dtype=np.int64)
    J = np.empty((len(XS), nx, nx))
    jacobians(XS, times, irefs, P, T, tix, vix, J)
    want, tol = central_differences(XS, times, irefs, P, T, tix, vix)
    assert np.all(np.isfinite(J)) and np.any(J != 0.0)
    diff = np.abs(J - want)
    assert np.all(diff <= tol), float(np.max(diff / np.maximum(tol, 1e-300)))


def test_jacobians_refuse_bad_indices(cases):
    P, T, tix, X0, sub, steps, dt = cases["own tables and references"]
    nx = X0.shape[1]
    out = np.empty((2, nx, nx))
    args = (np.ascontiguousarray(X0[:2]), np.zeros(2), np.zeros(2), P, T, tix)
    with pytest.raises(ValueError, match="variant index"):
        jacobians(*args, np.array([0, len(P)]), out)
    with pytest.raises(ValueError, match="out"):
        jacobians(*args, np.array([0, 1]), np.empty((2, nx, nx + 1)))
