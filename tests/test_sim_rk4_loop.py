"""The fixed-step loops: the register-held RK4 loop takes the same steps as the array form of
the same RK4, on the reference EMA and every shipped scene; a run in chunks (first/last steps
and the carry) gives the numbers of one call to the bit; a stroke end and a non-finite state
stop a run with their status; arrays of the wrong shape are refused before the loop runs."""

import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.loop.default_controller import default_controller
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.integrators import NCARRY, _paper, _rk4, scratch
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.tables import frozen_tables

from .conftest import ROOT, SCENE_FILES, SCENES

DATA_SCENES = sorted((ROOT / "servo_toolkit" / "data").glob("*.toml"))


@pytest.mark.parametrize("mode", ["sampled", "continuous"])
def test_scalar_loop_matches_array_loop(mode):
    scene = load_scene()
    controller, _ = controller_for(scene)
    model = build_model(scene, controller, ModelOptions(controller_mode=mode))
    P = fill(model, Reference.sine(math.radians(2.0), 8.0))
    x0 = initial_state(model, P)
    dt, n = 2e-5, 5000
    sub = int(round(model.sample_time / dt)) if mode == "sampled" else 0
    runs = []
    fig, snap = np.zeros(lo.NFIG), np.zeros((lo.NSNAP, model.nx + 2))
    for loop, extra, tail in ((_rk4, (), (fig, snap)), (_paper, (False,), ())):
        x = x0.copy()
        out = (np.empty(60), np.empty((60, model.nx)), np.empty((60, lo.NAUX)))
        work = scratch(model.nx, P.size) if loop is _rk4 else ()
        status = loop(x, P, model.T, 0.0, dt, 0, n, n, sub, 0.0, *extra, 100, *out, *tail, np.zeros(NCARRY), *work)
        runs.append((x, status, out))
    (xa, sa, oa), (xb, sb, ob) = runs
    assert sa[:3] == sb[:3] == (lo.OK, n, 51)
    assert np.array_equal(oa[0][:51], ob[0][:51])
    xa_rec, xb_rec = oa[1][:51], ob[1][:51]
    scale = np.maximum(np.max(np.abs(xb_rec), axis=0), 1e-300)
    assert np.max(np.abs(xa_rec - xb_rec) / scale) < 1e-10  # rounding only (fast-math order)
    assert np.max(np.abs(oa[2][:51] - ob[2][:51])) < 1e-10 * np.max(np.abs(ob[2][:51]))
    assert sa[3] == pytest.approx(sb[3], rel=1e-12)
    assert np.allclose(xa, xb, rtol=1e-10, atol=1e-14)
    assert abs(xa[2] - x0[2]) > 1e-4  # it moved


class Run:
    """One model's loop inputs (state, parameters, tables, step, steps, sample and record
    intervals) and its runs, whole or in chunks, through RK4 or the paper's scheme."""

    def __init__(self, model, P, x0, dt, n_steps, sub=None, rec=17):
        self.P, self.x0 = np.ascontiguousarray(P, dtype=float), np.array(x0, dtype=float)
        self.T = frozen_tables(model.T)
        self.dt, self.n_steps, self.rec = float(dt), int(n_steps), int(rec)
        if sub is None:
            sub = int(round(model.sample_time / dt)) if P[lo.CMODE] == lo.SAMPLED else 0
        self.sub, self.nx = int(sub), self.x0.size

    def _arrays(self):
        n_rec = self.n_steps // self.rec + 2
        return np.zeros(n_rec), np.zeros((n_rec, self.nx)), np.zeros((n_rec, lo.NAUX))

    def _ranges(self, chunks):
        edges = list(range(0, self.n_steps, chunks or self.n_steps)) + [self.n_steps]
        return list(zip(edges[:-1], edges[1:]))

    def rk4(self, chunks=None):
        """Every output of RK4 over the run, in one call or in calls of ``chunks`` steps."""
        x, out = self.x0.copy(), self._arrays()
        fig, snap, carry = np.full(lo.NFIG, np.nan), np.zeros((lo.NSNAP, self.nx + 2)), np.zeros(NCARRY)
        K, work, x0, PW = scratch(self.nx, self.P.size)
        work[:], x0[:], PW[:] = 0.0, 0.0, 0.0
        for first, last in self._ranges(chunks):
            ret = _rk4(x, self.P, self.T, 0.0, self.dt, first, last, self.n_steps, self.sub, 0.0, self.rec,
                       *out, fig, snap, carry, K, work, x0, PW)
            if ret[0] != lo.OK:
                break
        return {"ret": tuple(ret), "x": x, "out_t": out[0], "out_x": out[1], "out_aux": out[2], "fig": fig,
                "snap": snap, "carry": carry}

    def paper(self, paper=True, chunks=None):
        """Every output of the paper's scheme (``paper``) or RK4's array form over the run."""
        x, out, carry = self.x0.copy(), self._arrays(), np.zeros(NCARRY)
        for first, last in self._ranges(chunks):
            ret = _paper(x, self.P, self.T, 0.0, self.dt, first, last, self.n_steps, self.sub, 0.0, paper,
                         self.rec, *out, carry)
            if ret[0] != lo.OK:
                break
        return {"ret": tuple(ret), "x": x, "out_t": out[0], "out_x": out[1], "out_aux": out[2], "carry": carry}


def _ema(options=ModelOptions(), ref=Reference.sine(math.radians(2.0), 8.0), lossless=False):
    scene = load_scene(SCENES / "ema_reference.toml")
    if lossless:  # no loss: no smooth sign whose band RK4 takes in substeps
        from dataclasses import replace
        scene = replace(scene, stages=tuple(replace(s, efficiency=1.0) if hasattr(s, "efficiency") else s
                                            for s in scene.stages))
    model = build_model(scene, default_controller(scene), options)
    P = fill(model, ref)
    return model, P, initial_state(model, P)


@pytest.mark.parametrize("path", SCENE_FILES + DATA_SCENES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_shipped_scene_takes_the_same_steps_in_both_forms(path):
    """Every shipped scene with a motor-driven drivetrain, its default controller and a sine
    over a tenth of its stroke: RK4, its array form and the paper's scheme run to the end, and
    the two forms of RK4 agree to rounding (the same operations in another order)."""
    scene = load_scene(path)
    try:
        model = build_model(scene, default_controller(scene), ModelOptions())
    except Exception as exc:  # a scene without a motor-driven drivetrain (a platform's legs)
        pytest.skip(f"no fixed-step model: {exc}")
    lo_q, hi_q = model.stroke
    P = fill(model, Reference.sine(0.05 * (hi_q - lo_q), 2.0))
    run = Run(model, P, initial_state(model, P), 2.5e-5, 5000)
    held, array, paper = run.rk4(), run.paper(False), run.paper(True)
    n = held["ret"][2]
    assert held["ret"][:3] == array["ret"][:3] == paper["ret"][:3] == (lo.OK, run.n_steps, n)
    assert held["ret"][3] > 0.0  # it drove
    assert np.array_equal(held["out_t"][:n], array["out_t"][:n])
    scale = np.maximum(np.max(np.abs(array["out_x"][:n]), axis=0), 1e-300)
    assert np.max(np.abs(held["out_x"][:n] - array["out_x"][:n]) / scale) < 1e-10


@pytest.mark.parametrize("case", ["sampled", "full chain stick"])
def test_chunks_give_the_numbers_of_one_call(case):
    """Calls of 7 and 1000 steps (ends between two controller samples and two records, and in
    the full chain between located friction switches) give the numbers of one call bit for
    bit: the state, the records, the figures, the snapshots and the carry."""
    options = ModelOptions(chain="full", friction="stick") if case != "sampled" else ModelOptions()
    model, P, x0 = _ema(options)
    run = Run(model, P, x0, model.sample_time / 20, 6000, rec=37)
    whole, whole_paper = run.rk4(), run.paper(True)
    assert whole["ret"][0] == whole_paper["ret"][0] == lo.OK
    for chunks in (7, 1000):
        got = run.rk4(chunks)
        assert got["ret"] == whole["ret"]
        for key in ("x", "out_t", "out_x", "out_aux", "fig", "snap", "carry"):
            assert np.array_equal(got[key], whole[key], equal_nan=True), (chunks, key)
        got = run.paper(True, chunks)
        assert got["ret"] == whole_paper["ret"]
        for key in ("x", "out_t", "out_x", "out_aux", "carry"):
            assert np.array_equal(got[key], whole_paper[key], equal_nan=True), (chunks, key)


def test_stroke_end():
    """A ramp past the stroke stops RK4 and the paper's scheme with STROKE_END (RK4's figures
    say so too)."""
    model, P, x0 = _ema(ref=Reference.ramp(5.0))
    run = Run(model, P, x0, 2.5e-5, 40000)
    got = run.rk4()
    assert got["ret"][0] == lo.STROKE_END and got["fig"][lo.F_STATUS] == lo.STROKE_END
    assert 0 < got["ret"][1] < run.n_steps
    assert run.paper(True)["ret"][0] == lo.STROKE_END


def test_non_finite_state():
    """A NaN in the initial state stops both loops at step 0 with NONFINITE and one record; a
    step far beyond stability blows the run up within the run: NONFINITE, a state that is not
    finite (a chain without a smooth sign, whose band RK4 would take in substeps at every
    reversal of the oscillation the step excites: bounded there, and refused by the stability
    check before any run)."""
    model, P, x0 = _ema()
    x0[3] = np.nan
    run = Run(model, P, x0, 2.5e-5, 100)
    assert run.rk4()["ret"][:3] == (lo.NONFINITE, 0, 1)
    assert run.paper(True)["ret"][:3] == (lo.NONFINITE, 0, 1)
    model, P, x0 = _ema(ModelOptions(stroke_end="stop", friction="off"), lossless=True)
    run = Run(model, P, x0, 5e-3, 3000, rec=1)
    for got in (run.rk4(), run.paper(True)):
        assert got["ret"][0] == lo.NONFINITE and got["ret"][1] < run.n_steps
        assert not np.all(np.isfinite(got["x"]))


def test_the_arrays_are_checked():
    """Wrong shapes are refused before the loop runs: the parameters' scratch, the records, the
    carry."""
    model, P, x0 = _ema()
    nx = model.nx
    out = (np.zeros(5), np.zeros((5, nx)), np.zeros((5, lo.NAUX)))
    K, work, x1, PW = scratch(nx, P.size)
    args = [x0.copy(), P, frozen_tables(model.T), 0.0, 1e-5, 0, 3, 3, 0, 0.0, 1, *out, np.zeros(lo.NFIG),
            np.zeros((lo.NSNAP, nx + 2)), np.zeros(NCARRY), K, work, x1, PW]
    assert _rk4(*args)[:3] == (lo.OK, 3, 4)
    bad = list(args)
    bad[-1] = np.zeros((4, 3))
    with pytest.raises(ValueError, match="PW"):
        _rk4(*bad)
    bad = list(args)
    bad[12] = np.zeros((5, nx + 1))
    with pytest.raises(ValueError, match="out_x"):
        _rk4(*bad)
    with pytest.raises(ValueError, match="carry"):
        _paper(x0.copy(), P, frozen_tables(model.T), 0.0, 1e-5, 0, 3, 3, 0, 0.0, True, 1, *out, np.zeros(3))
