"""The C fixed-step loops (servo_toolkit._physics: integrate.h, split_step.h, node_switch.h,
switch_loop.h) against the numba originals (servo_toolkit.sim.integrators._rk4 and _paper),
side by side on the real models: the reference EMA (sampled with each speed estimator,
continuous, the full chain), the shipped scenes, friction that holds (stick, reversals and
breakaways located inside the step, two switches in one step, a lossy gear holding, the full
chain's intermediate node sticking), a stroke end, a non-finite state, the paper's scheme and
the array form of RK4, and runs in chunks (first/last/carry).

Both loops run from the same state with the same scratch arrays; every output is compared:
the return tuple's status, step and record count exactly, the records (times, states, aux),
the figures, the snapshots, the carry and the final state to a relative 1e-12 of each
column's scale (the numba code was compiled with fast-math and contracts products into FMAs,
the C does neither: a few ulps per step, which RK4 carries on without growing over these
runs). Where a run's difference is larger, the test says why. These comparisons go when numba
goes; the permanent net is tests/rhs_reference.py and the suite.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from servo_toolkit.components.ball_screw import BallScrew
from servo_toolkit.components.compliance import Compliance, Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.components.stage_friction import StageFriction
from servo_toolkit.loop.default_controller import default_controller
from servo_toolkit.scene.loader import Scene, load_scene
from servo_toolkit.sim import ModelOptions, Reference, build_model
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.integrators import NCARRY, _paper, _rk4, scratch
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.tables import frozen_tables

from .conftest import ROOT, SCENE_FILES, SCENES

ck = pytest.importorskip("servo_toolkit._physics._kernels")

#: relative agreement of every value (fast-math rounding only)
REL = 1e-12
DATA_SCENES = sorted((ROOT / "servo_toolkit" / "data").glob("*.toml"))


class Run:
    """One model's loop inputs: state, parameters, tables, step, steps, sample and record interval."""

    def __init__(self, model, P, x0, dt, n_steps, sub=None, rec=17, iref=0.0):
        self.model, self.P, self.x0 = model, np.ascontiguousarray(P, dtype=float), np.array(x0, dtype=float)
        self.T = frozen_tables(model.T)
        self.dt, self.n_steps, self.rec, self.iref = float(dt), int(n_steps), int(rec), float(iref)
        if sub is None:
            sub = int(round(model.sample_time / dt)) if P[lo.CMODE] == lo.SAMPLED else 0
        self.sub = int(sub)
        self.nx = self.x0.size

    def arrays(self):
        n_rec = self.n_steps // self.rec + 2
        return (np.zeros(n_rec), np.zeros((n_rec, self.nx)), np.zeros((n_rec, lo.NAUX)))

    def rk4(self, loop, chunks=None):
        """Every output of ``loop`` (numba ``_rk4`` or C ``ck.rk4``) over the run, in one call or
        calls of ``chunks`` steps."""
        x = self.x0.copy()
        out = self.arrays()
        fig, snap, carry = np.full(lo.NFIG, np.nan), np.zeros((lo.NSNAP, self.nx + 2)), np.zeros(NCARRY)
        K, work, x0, PW = scratch(self.nx, self.P.size)
        work[:], x0[:], PW[:] = 0.0, 0.0, 0.0  # the same start for both (np.empty in scratch)
        for first, last in self.ranges(chunks):
            ret = loop(x, self.P, self.T, 0.0, self.dt, first, last, self.n_steps, self.sub, self.iref, self.rec,
                       *out, fig, snap, carry, K, work, x0, PW)
            if ret[0] != lo.OK:
                break
        return {"ret": tuple(ret), "x": x, "out_t": out[0], "out_x": out[1], "out_aux": out[2], "fig": fig,
                "snap": snap, "carry": carry, "n_rec": ret[2]}

    def paper(self, loop, paper=True, chunks=None):
        x = self.x0.copy()
        out = self.arrays()
        carry = np.zeros(NCARRY)
        for first, last in self.ranges(chunks):
            ret = loop(x, self.P, self.T, 0.0, self.dt, first, last, self.n_steps, self.sub, self.iref, paper,
                       self.rec, *out, carry)
            if ret[0] != lo.OK:
                break
        return {"ret": tuple(ret), "x": x, "out_t": out[0], "out_x": out[1], "out_aux": out[2], "carry": carry,
                "n_rec": ret[2]}

    def ranges(self, chunks):
        if chunks is None:
            return [(0, self.n_steps)]
        edges = list(range(0, self.n_steps, chunks)) + [self.n_steps]
        return list(zip(edges[:-1], edges[1:]))


def rel_diff(a, b):
    """Largest difference of a and b relative to each column's scale (rows x columns, or a vector
    relative to its own largest value); NaNs must match."""
    a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
    assert a.shape == b.shape
    nan = np.isnan(a) | np.isnan(b)
    assert np.array_equal(np.isnan(a), np.isnan(b))
    a, b = np.where(nan, 0.0, a), np.where(nan, 0.0, b)
    scale = np.maximum(np.max(np.abs(b), axis=0), 1e-300)
    return float(np.max(np.abs(a - b) / scale, initial=0.0))


def compare(got, want, rel=REL):
    """The largest relative difference over every output; asserts the counts exactly."""
    assert got["ret"][:3] == want["ret"][:3], (got["ret"], want["ret"])
    assert all(type(g) is type(w) for g, w in zip(got["ret"], want["ret"]))
    n = want["n_rec"]
    worst = {"out_t": rel_diff(got["out_t"][:n, None], want["out_t"][:n, None]),
             "out_x": rel_diff(got["out_x"][:n], want["out_x"][:n]),
             "out_aux": rel_diff(got["out_aux"][:n], want["out_aux"][:n]),
             "x": rel_diff(got["x"][None], want["x"][None]),
             "ret": rel_diff(np.array(got["ret"][3:])[:, None], np.array(want["ret"][3:])[:, None])}
    if "fig" in want:
        worst["fig"] = rel_diff(got["fig"][None], want["fig"][None])
        worst["snap"] = rel_diff(got["snap"], want["snap"])
        worst["carry"] = rel_diff(got["carry"][None], want["carry"][None])
    else:
        worst["carry"] = rel_diff(got["carry"][:5][None], want["carry"][:5][None])
    assert max(worst.values()) <= rel, worst
    return max(worst.values())


def both_rk4(run, chunks=None, rel=REL):
    want = run.rk4(_rk4, chunks)
    got = run.rk4(ck.rk4, chunks)
    compare(got, want, rel)
    return got, want


def both_paper(run, paper=True, chunks=None, rel=REL):
    want = run.paper(_paper, paper, chunks)
    got = run.paper(ck.paper, paper, chunks)
    compare(got, want, rel)
    return got, want


# --- the models -----------------------------------------------------------------------------

def ema(options=ModelOptions(), ref=Reference.sine(math.radians(2.0), 8.0), path=SCENES / "ema_reference.toml"):
    scene = load_scene(path)
    model = build_model(scene, default_controller(scene), options)
    P = fill(model, ref)
    return model, P, initial_state(model, P)


def two_nodes():
    """test_two_switches' stiff two-mass chain: motor and load reverse within one step."""
    motor = DCMotor(resistance=1.0, inductance=0.0, torque_constant=0.1, back_emf_constant=0.1, rotor_inertia=1e-3,
                    viscous_friction=0.0, coulomb_friction=0.01, static_friction=0.015, voltage_limit=100.0,
                    current_limit=50.0)
    sc = Scene("two nodes", motor=motor, stages=(Compliance("shaft", 2000.0),),
               load=Load(inertia=1e-2, coulomb_friction=0.1, static_friction=0.15))
    model = build_model(sc, None, ModelOptions(backlash=False, friction="stick"))
    P = fill(model, Reference.voltage(0.0, 3.0, 2.0))
    return model, P, initial_state(model, P, at_rest=True)


def lossy_screw(eta=5.0 / 7.0, volts=0.0, swing=6.0):
    """test_gear_holds' rigid ball screw under a hinge force: the lossy gear holds at rest."""
    motor = DCMotor(resistance=0.5, inductance=0.0, torque_constant=0.2, back_emf_constant=0.2, rotor_inertia=2e-4,
                    viscous_friction=1e-4, coulomb_friction=0.02, static_friction=0.03, voltage_limit=100.0,
                    current_limit=50.0)
    sc = Scene("lossy screw", motor=motor,
               stages=(BallScrew("screw", lead=0.005, screw_inertia=1e-5, nut_mass=0.5, efficiency=eta),),
               load=Load(inertia=10.0, hinge_moment=2000.0, coulomb_friction=50.0, static_friction=80.0))
    model = build_model(sc, None, ModelOptions(friction="stick"))
    P = fill(model, Reference.voltage(volts, swing, 3.0))
    return model, P, initial_state(model, P, at_rest=True)


def wheel_and_load():
    """test_two_switches' full chain: the wheel (an intermediate node) and the load reverse within
    one step, both flagged at once (the earliest of several located switches)."""
    motor = DCMotor(resistance=1.0, inductance=0.0, torque_constant=0.1, back_emf_constant=0.1,
                    rotor_inertia=2.5e-4, viscous_friction=0.0, coulomb_friction=0.0, current_limit=50.0,
                    voltage_limit=100.0)
    stages = (GearTrain("gear A", ratio=2.0, inertias=(0.0, 1e-3), torsional_stiffness=200.0),
              GearTrain("gear B", ratio=1.0, inertias=(0.0, 0.0), torsional_stiffness=2000.0))
    sc = Scene("wheel and load", motor=motor, stages=stages,
               load=Load(inertia=1e-2, coulomb_friction=0.1, static_friction=0.15),
               stage_friction=(StageFriction(0.01, 0.015), None))
    model = build_model(sc, None, ModelOptions(chain="full", friction="stick", backlash=False, inductance=False))
    P = fill(model, Reference.voltage(0.0, 3.0, 2.0))
    return model, P, initial_state(model, P, at_rest=True)


def node_chain():
    """test_node_friction's two-gear chain: the wheel (an intermediate node) sticks and breaks away."""
    motor = DCMotor(resistance=1.0, inductance=0.0, torque_constant=0.1, back_emf_constant=0.1, rotor_inertia=1e-4,
                    viscous_friction=0.0, coulomb_friction=0.0, current_limit=50.0, voltage_limit=100.0)
    stages = (GearTrain("gear A", ratio=2.0, inertias=(0.0, 2e-4), torsional_stiffness=50.0),
              GearTrain("gear B", ratio=5.0, inertias=(0.0, 0.0), torsional_stiffness=500.0))
    sc = Scene("two gears", motor=motor, stages=stages, load=Load(inertia=0.05, hinge_moment=0.0),
               stage_friction=(StageFriction(0.02, 0.03, 0.5, 1e-4), None))
    model = build_model(sc, None, ModelOptions(chain="full", friction="stick", backlash=False, inductance=False))
    P = fill(model, Reference.voltage(0.3, 1.0, 5.0))
    x0 = initial_state(model, P, at_rest=True)
    o = int(model.P[lo.OFF_NODE])
    x0[[1, 3, o + 1]] = 0.3
    return model, P, x0


# --- the comparisons ------------------------------------------------------------------------

ESTIMATORS = [None, "ideal", "difference", "kalman"]


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_reference_ema_sampled_with_each_estimator(estimator):
    """The reference EMA under its sampled controller, each speed estimator: RK4 and the paper's
    scheme. The Kalman estimator's acceleration state is its gain times the innovation, a
    difference of two nearly equal angles: it carries the angles' rounding (a few ulps) times
    the gain, 1e-12 of its scale over 8000 steps; the other states stay within 1e-13."""
    model, P, x0 = ema(ModelOptions(speed_estimator=estimator))
    run = Run(model, P, x0, 2.5e-5, 8000)
    rel = 1e-11 if estimator == "kalman" else REL
    both_rk4(run, rel=rel)
    both_paper(run, True, rel=rel)


@pytest.mark.parametrize("mode", ["continuous", "open"])
def test_reference_ema_continuous_and_array_form(mode):
    """The continuous controller (its states move in every stage) and RK4's array form (_paper with
    paper=False); the open loop under a sine voltage."""
    if mode == "open":
        scene = load_scene(SCENES / "ema_reference.toml")
        model = build_model(scene, None, ModelOptions())
        P = fill(model, Reference.voltage(2.0, 4.0, 5.0))
        x0 = initial_state(model, P, at_rest=True)
    else:
        model, P, x0 = ema(ModelOptions(controller_mode="continuous"))
    run = Run(model, P, x0, 2.5e-5, 8000)
    both_rk4(run)
    both_paper(run, True)
    both_paper(run, False)


@pytest.mark.parametrize("path", SCENE_FILES + DATA_SCENES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_shipped_scenes(path):
    """Every shipped scene with a motor-driven drivetrain, its default controller and a sine over
    a tenth of its stroke: RK4, the paper's scheme and the array form."""
    scene = load_scene(path)
    try:
        controller = default_controller(scene)
        model = build_model(scene, controller, ModelOptions())
    except Exception as exc:  # a scene without a motor-driven drivetrain (a platform's legs)
        pytest.skip(f"no fixed-step model: {exc}")
    lo_q, hi_q = model.stroke
    P = fill(model, Reference.sine(0.05 * (hi_q - lo_q), 2.0))
    x0 = initial_state(model, P)
    run = Run(model, P, x0, 2.5e-5, 5000)
    got, want = both_rk4(run)
    assert want["ret"][3] > 0.0  # it drove
    both_paper(run, True)
    both_paper(run, False)


#: the reference EMA's full chain with friction that holds at its intermediate nodes: a node's
#: speed passes through 0 there, where its stick law decides between holding and sliding and
#: its sliding law is steep, so a few ulps of the node's speed (fast-math against plain C) come
#: out as a relative 1e-13 of the node rate's scale within 50 steps; and RK4 locates the
#: switches by an Illinois bracket closed within TAU_TOL = 1e-12 of the step, so trial speeds
#: an ulp apart move the switch's instant by up to that. Measured over 8000 steps: 6e-12 (RK4),
#: 2e-11 (the paper's scheme, which locates nothing: the stick law alone), 9e-12 (array form)
SWITCH_REL = 1e-10

FRICTION_CASES = {
    "two switches in one step": (two_nodes, 1e-4, 10000, REL),
    "lossy gear holds (eta 0.9)": (lambda: lossy_screw(0.9), 1e-4, 10000, REL),
    "lossy gear holds (eta 5/7)": (lambda: lossy_screw(5.0 / 7.0), 1e-4, 10000, REL),
    "self-locking screw": (lambda: lossy_screw(0.4, 0.0, 12.0), 1e-4, 10000, REL),
    "intermediate node sticks": (node_chain, 1e-4, 3000, REL),
    "wheel and load in one step": (wheel_and_load, 6.25e-5, 16000, REL),
    "ema stick": (lambda: ema(ModelOptions(friction="stick")), 2.5e-5, 8000, REL),
    "ema full chain stick": (lambda: ema(ModelOptions(chain="full", friction="stick")), 2.5e-5, 8000, SWITCH_REL),
}


@pytest.mark.parametrize("case", list(FRICTION_CASES))
def test_friction_that_holds(case):
    """Friction that holds: speed reversals and breakaways located within the step (the motor side
    and the load, two in one step, a lossy gear holding at rest, the full chain's intermediate
    nodes), and the paper's scheme's stop at a reversal (Karnopp)."""
    make, dt, n, rel = FRICTION_CASES[case]
    model, P, x0 = make()
    assert P[lo.STICK] > 0.0
    run = Run(model, P, x0, dt, n)
    got, want = both_rk4(run, rel=rel)
    both_paper(run, True, rel=rel)
    both_paper(run, False, rel=rel)
    speeds = want["out_x"][:want["n_rec"], [1, 3]]
    assert np.any(speeds == 0.0) or case == "intermediate node sticks"  # a node held at rest


def test_stroke_end():
    """A ramp past the stroke: both loops stop at the same step with STROKE_END."""
    model, P, x0 = ema(ref=Reference.ramp(5.0))
    run = Run(model, P, x0, 2.5e-5, 40000)
    got, _ = both_rk4(run)
    assert got["ret"][0] == lo.STROKE_END and got["fig"][lo.F_STATUS] == lo.STROKE_END
    got, _ = both_paper(run, True)
    assert got["ret"][0] == lo.STROKE_END


def test_non_finite_state():
    """A NaN in the initial state stops both loops at step 0 (NONFINITE, one record); a step far
    beyond stability blows the run up within a few steps: the same status, step and records
    (the records up to three steps before it agree; the state at the blow-up is overflow, 1e94
    and beyond, where each step multiplies the rounding by orders of magnitude: both are
    non-finite somewhere, not necessarily in the same states)."""
    model, P, x0 = ema()
    x0[3] = np.nan
    run = Run(model, P, x0, 2.5e-5, 100)
    got, _ = both_rk4(run)
    assert got["ret"][:3] == (lo.NONFINITE, 0, 1)
    both_paper(run, True)
    model, P, x0 = ema(ModelOptions(stroke_end="stop"))
    run = Run(model, P, x0, 5e-3, 3000, rec=1)
    for want, got in ((run.rk4(_rk4), run.rk4(ck.rk4)), (run.paper(_paper, True), run.paper(ck.paper, True))):
        assert got["ret"][:3] == want["ret"][:3] and want["ret"][0] == lo.NONFINITE
        n = want["n_rec"]
        assert np.array_equal(got["out_t"][:n], want["out_t"][:n])
        assert rel_diff(got["out_x"][:n - 3], want["out_x"][:n - 3]) <= REL
        assert not np.all(np.isfinite(got["x"])) and not np.all(np.isfinite(want["x"]))


@pytest.mark.parametrize("case", ["sampled", "full chain stick"])
def test_chunks_give_the_numbers_of_one_call(case):
    """Calls of 7 and 1000 steps (ends between two controller samples and two records) give the C
    loops' numbers of one call bit for bit, and the numba loops' in the same chunks."""
    options = ModelOptions(chain="full", friction="stick") if case != "sampled" else ModelOptions()
    model, P, x0 = ema(options)
    run = Run(model, P, x0, model.sample_time / 20, 6000, rec=37)
    rel = SWITCH_REL if case != "sampled" else REL
    whole = run.rk4(ck.rk4)
    whole_paper = run.paper(ck.paper, True)
    for chunks in (7, 1000):
        got = run.rk4(ck.rk4, chunks)
        assert got["ret"] == whole["ret"]
        for key in ("x", "out_t", "out_x", "out_aux", "fig", "snap", "carry"):
            assert np.array_equal(got[key], whole[key], equal_nan=True), (chunks, key)
        compare(got, run.rk4(_rk4, chunks), rel)
        got = run.paper(ck.paper, True, chunks)
        assert got["ret"] == whole_paper["ret"]
        for key in ("x", "out_t", "out_x", "out_aux", "carry"):
            assert np.array_equal(got[key], whole_paper[key], equal_nan=True), (chunks, key)
        compare(got, run.paper(_paper, True, chunks), rel)


def test_the_arrays_are_checked():
    """Wrong shapes are refused before the loop runs (numba trusted them)."""
    model, P, x0 = ema()
    nx = model.nx
    out = (np.zeros(5), np.zeros((5, nx)), np.zeros((5, lo.NAUX)))
    K, work, x1, PW = scratch(nx, P.size)
    args = [x0.copy(), P, frozen_tables(model.T), 0.0, 1e-5, 0, 3, 3, 0, 0.0, 1, *out, np.zeros(lo.NFIG),
            np.zeros((lo.NSNAP, nx + 2)), np.zeros(NCARRY), K, work, x1, PW]
    assert ck.rk4(*args)[:3] == (lo.OK, 3, 4)
    bad = list(args)
    bad[-1] = np.zeros((4, 3))
    with pytest.raises(ValueError, match="PW"):
        ck.rk4(*bad)
    bad = list(args)
    bad[12] = np.zeros((5, nx + 1))
    with pytest.raises(ValueError, match="out_x"):
        ck.rk4(*bad)
    with pytest.raises(ValueError, match="carry"):
        ck.paper(x0.copy(), P, frozen_tables(model.T), 0.0, 1e-5, 0, 3, 3, 0, 0.0, True, 1, *out, np.zeros(3))


def test_speed_against_numba(capsys):
    """Steps per second, C against numba, on the reference EMA (sampled, RK4): reported, not asserted."""
    model, P, x0 = ema()
    run = Run(model, P, x0, 2.5e-5, 40000, rec=40)
    rates = {}
    for name, loop in (("numba", _rk4), ("C", ck.rk4)):
        run.rk4(loop)  # warm
        best = math.inf
        for _ in range(3):
            start = time.perf_counter()
            run.rk4(loop)
            best = min(best, time.perf_counter() - start)
        rates[name] = run.n_steps / best
    with capsys.disabled():
        print(f"\nRK4 on the reference EMA: C {rates['C']:.3g} steps/s, numba {rates['numba']:.3g} steps/s "
              f"(C/numba {rates['C'] / rates['numba']:.2f})")
