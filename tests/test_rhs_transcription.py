"""The compiled right-hand side equals its plain-Python transcription (tests/rhs_reference.py)
at random states of the models the shipped scenes give, under several model options.

Each case builds one model (once for the module) from a scene in scenes/ (the package's
data/ema_reference.toml is the same file as scenes/ema_reference.toml) and draws states near
the physically sensible range: positions within the stroke (past its ends where an end stop
acts), speeds up to the motor's no-load speed at the voltage limit, exactly zero speeds
(friction that holds), currents and PI integrals across their limits (the clamps), each
compliance's deflection across its play's edges and into contact, controller states around
the current limit, times over the commands' transients. Cases marked "(slots)" also set
parameter slots a shipped scene leaves at 0 but other scenes and the kernels' callers set:
the load's friction and a Stribeck drop, the held sliding direction and the breakaway gauges
of the switch location, friction at the full chain's intermediate nodes, the cam paper's play
operator.

The reference EMA runs its designed loop; ema_robust and ema_sizing, the same physics with
other requirements, run the fallback cascade (``default_controller``), sparing two designs.

Agreement (:func:`_tolerance`): the kernels are compiled with fast-math (-ffast-math
-fno-finite-math-only: reassociated sums, fused multiply-adds, reciprocals for divisions,
signed zeros ignored; NaN and infinity kept) and use their own branch-free tanh and exp
(``vmath.h``, within 1 ulp of the C library's, which the transcription uses): the two may round
differently in the last bits of every sum. A sum's rounding error is of the order of eps
times its terms' magnitudes, not its result's: the deflection p - q beyond the play, a moment
that nearly cancels the hinge moment or a breakaway level lose digits in either program. The
tolerance is therefore RTOL = 1e-12 of the result and of its full scale (its largest magnitude
over 64 seeded examples of the case: the size of the terms a cancellation leaves digits of),
plus 1e3 eps times the result's sensitivity to its inputs, sum_j |d f / d u_j| |u_j| over the
state, time and held current (what a rounding of the inputs alone changes; one-sided
differences of the transcription), and nothing else. Measured over 300 examples of each case:
5 % to three quarters of the examples agree to the last bit in every result; the largest
difference is 1e-13 of its result's full scale and used at most 0.5 % of the tolerance; a
result above 1e-6 of its full scale agreed to 2e-13 of itself, to 8e-11 where the continuous
motion controller's output (a sum of terms that cancel while the loop tracks) sets the current
and so the torque. A wrong law fails it, and so does a parameter off by one part in 1e9
(:func:`test_a_small_error_in_a_parameter_fails_the_comparison`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from servo_toolkit.loop.controller import Feedforward
from servo_toolkit.loop.default_controller import default_controller
from servo_toolkit.loop.shaper import InputShaper
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.kernel import rhs as compiled_rhs
from servo_toolkit.sim.reference import fill, initial_state

from . import rhs_reference
from .conftest import SCENES

#: relative agreement of a result, and of its sensitivity to the inputs in units of eps
RTOL, SENSITIVITY_ULPS = 1e-12, 1e3
EPS = np.finfo(float).eps
#: relative step of the one-sided differences that measure the sensitivity
STEP = 1e-8
EXAMPLES = 100


@dataclass(frozen=True)
class Case:
    """One model kind: a scene, its controller (``"designed"``, ``"default"``, the designed one
    ``"+ff"`` with a feedforward and ``"+shaper"`` a command shaper, or None: open loop), the
    model options, the references it runs and the synthetic slots it sets."""

    scene: str
    controller: str | None
    options: ModelOptions
    refs: str = "sine"
    slots: tuple = ()


TWO, FULL = ModelOptions(chain="two_mass"), ModelOptions(chain="full")
STICK = {"friction": "stick"}
CONT = {"controller_mode": "continuous"}
FF = Feedforward(velocity=0.02, acceleration=1e-3, model=True, inertia_scale=1.1)

CASES = {
    "ema two-mass sampled smooth": Case("ema_reference", "designed", TWO),
    "ema two-mass sampled stick (slots)": Case("ema_reference", "designed", replace(TWO, **STICK),
                                               slots=("load_friction", "switch")),
    "ema two-mass no play, constant inertia, lossless, end stop": Case(
        "ema_reference", "designed", replace(TWO, backlash=False, variable_inertia=False, efficiency=False,
                                             stroke_end="stop")),
    "ema two-mass play operator (slots)": Case("ema_reference", "designed", TWO, slots=("paper",)),
    "ema two-mass continuous, feedforward, shaper (slots)": Case(
        "ema_reference", "designed+ff+shaper", replace(TWO, **CONT), refs="all", slots=("lead",)),
    "ema two-mass open loop": Case("ema_reference", None, TWO, refs="voltage"),
    "ema full chain sampled smooth": Case("ema_reference", "designed", FULL),
    "ema full chain sampled stick, end stop (slots)": Case(
        "ema_reference", "designed", replace(FULL, stroke_end="stop", **STICK),
        slots=("load_friction", "switch", "node_friction")),
    "ema full chain continuous, feedforward": Case("ema_reference", "designed+ff", replace(FULL, **CONT),
                                                   refs="moves"),
    "ema rigid stick, end stop (slots)": Case("ema_reference", "designed",
                                              ModelOptions(compliance=False, stroke_end="stop", **STICK),
                                              slots=("load_friction", "switch")),
    "ema rigid without inductance, continuous, feedforward": Case(
        "ema_reference", "designed+ff", ModelOptions(compliance=False, inductance=False, **CONT), refs="moves"),
    "ema rigid near self-locking, open loop, stick": Case("ema_near_lock", None,
                                                          ModelOptions(compliance=False, inductance=False, **STICK),
                                                          refs="voltage", slots=("switch",)),
    "ema_robust two-mass sampled": Case("ema_robust", "default", TWO),
    "ema_sizing full chain stick": Case("ema_sizing", "default", replace(FULL, **STICK)),
    "emps rigid sampled smooth": Case("emps", "designed", ModelOptions()),
    "emps rigid sampled stick (slots)": Case("emps", "designed", ModelOptions(**STICK),
                                             slots=("load_friction", "switch")),
    "emps rigid continuous, feedforward, shaper, end stop": Case("emps", "designed+ff+shaper",
                                                         ModelOptions(stroke_end="stop", **CONT), refs="all"),
    "roller screw rigid lossy continuous": Case("linear_roller_screw_actuator", "designed", ModelOptions(),
                                                refs="moves"),
    "roller screw continuous, feedforward, end stop": Case("linear_roller_screw_actuator", "designed+ff",
                                                           ModelOptions(stroke_end="stop"), refs="moves"),
    "cam rigid periodic smooth": Case("cam_follower", "designed", ModelOptions(), refs="moves"),
    "cam rigid periodic stick (slots)": Case("cam_follower", "designed", ModelOptions(**STICK),
                                             slots=("switch",)),
    "cam open loop": Case("cam_follower", None, ModelOptions(), refs="voltage"),
}


# --- building the models --------------------------------------------------------------------

def _scene(name):
    if name == "ema_near_lock":
        # the reference EMA with a near-self-locking ball screw (efficiency 0.3, back-driven
        # below 0.1): the loss blend's rounded |sg| branch and a self-locking gear at rest
        scene = load_scene(SCENES / "ema_reference.toml")
        stages = tuple(replace(s, efficiency=0.3) if type(s).__name__ == "BallScrew" else s for s in scene.stages)
        return replace(scene, stages=stages)
    return load_scene(SCENES / f"{name}.toml")


def _references(model, kind):
    """The references a case's parameters are filled with."""
    lo_s, hi_s = model.stroke
    span = hi_s - lo_s
    if kind == "voltage":
        return [Reference.voltage(3.0, swing=2.0, frequency=5.0), Reference.voltage(-1.0)]
    sine = Reference.sine(0.1 * span, 3.0)
    if kind == "sine":
        return [sine]
    v = span / 0.5
    move = Reference.move(0.3 * span, v, v / 0.1, v / 0.01, at=0.2)
    times = 0.05 * np.arange(12)
    values = 0.1 * span * np.sin(2 * np.pi * times / 0.6)
    table = Reference.table(times, values, periodic=True)
    if kind == "moves":
        return [sine, move, table]
    return [Reference("hold"), sine, Reference.step(0.05 * span, at=0.3), Reference.ramp(0.2 * span, at=0.1),
            move, Reference.table(times + 0.1, values), table]


def _with_slots(model, P, slots):
    """Parameter variants with the case's synthetic slots set (the drawn ones, DIR_M, DIR_L,
    HOLD_GAUGE, are set per example)."""
    out = [P]
    n0, torque = _ratio(model, P), _torque_scale(model, P)
    if "load_friction" in slots:
        Q = P.copy()
        Q[lo.TS_L], Q[lo.TC_L] = 0.05 * torque, 0.04 * torque
        Q[lo.INV_VS_L] = 1.0 / (0.01 * _speed_scale(model, P))
        Q[lo.TS_M], Q[lo.INV_VS_M] = 1.5 * P[lo.TC], 1.0 / (0.02 * n0 * _speed_scale(model, P))
        out.append(Q)
    if "node_friction" in slots:
        nm = int(P[lo.NMID])
        block = np.zeros(lo.NF_STRIDE * nm)
        for j in range(nm):
            b = lo.NF_STRIDE * j
            block[b + lo.NF_TC], block[b + lo.NF_TS] = 0.01 * torque, 0.015 * torque
            block[b + lo.NF_INV_VS] = (1.0 / (0.01 * _speed_scale(model, P))) if j % 2 else math.inf
            block[b + lo.NF_VISC] = 0.001 * torque / _speed_scale(model, P)
            block[b + lo.NF_DIR] = (0.0, 1.0, -1.0)[j % 3]
        Q = P.copy()
        Q[lo.NODE_FRIC] = Q.size
        out.append(np.concatenate([Q, block]))
    if "lead" in slots:  # the feedforward current half a sample ahead (a sampled loop's)
        out += [Q.copy() for Q in out]
        for Q in out[len(out) // 2:]:
            Q[lo.FF_LEAD] = 5e-4
    if "paper" in slots:
        Q = P.copy()
        Q[lo.PAPER] = 1.0
        out = [Q]
    return out


def case_builder(ema, table, full_scale: bool = True):
    """``get(case)`` of the cases of ``table``: ``(model, parameter variants)``, with the full
    scale of the results when ``full_scale``, each built once (the reference EMA's designed
    loop: the session's). A controller kind is ``base[+ff][+shaper][+schedule]``."""
    from servo_toolkit.loop.schedule import gain_schedule
    scenes = {"ema_reference": (ema[0], {"designed": ema[1]})}  # scene, its controllers by kind
    cases = {}

    def controller(scene_name, kind):
        scene, controllers = scenes[scene_name]
        if kind not in controllers:
            base, *extras = kind.split("+")
            if extras:
                ctrl = controller(scene_name, base)
                if "ff" in extras:
                    ctrl = replace(ctrl, feedforward=FF)
                if "shaper" in extras:
                    ctrl = replace(ctrl, shaper=InputShaper.design("zvd", 8.0, 0.05))
                if "schedule" in extras:
                    ctrl = replace(ctrl, schedule=gain_schedule(scene))
                controllers[kind] = ctrl
            else:
                controllers[kind] = controller_for(scene)[0] if base == "designed" else default_controller(scene)
        return controllers[kind]

    def get(name):
        if name not in cases:
            case = table[name]
            if case.scene not in scenes:
                scenes[case.scene] = _scene(case.scene), {}
            ctrl = None if case.controller is None else controller(case.scene, case.controller)
            model = build_model(scenes[case.scene][0], ctrl, case.options)
            params = [p for ref in _references(model, case.refs)
                      for p in _with_slots(model, fill(model, ref), case.slots)]
            cases[name] = (model, params, _full_scale(name, model, params)) if full_scale else (model, params)
        return cases[name]

    return get


@pytest.fixture(scope="module")
def built(ema):
    """``built(case)``: ``(model, parameter variants, full scale of the results)`` of a case,
    each built once for the module."""
    return case_builder(ema, CASES)


# --- drawing states -------------------------------------------------------------------------

class Draws:
    """The draws of one example: from hypothesis (``data``), or from a seeded generator
    (``rng``) for a case's full scale."""

    def __init__(self, data=None, rng=None):
        self.data, self.rng = data, rng

    def uniform(self, a, b):
        if self.data is None:
            return float(self.rng.uniform(a, b))
        return self.data.draw(st.floats(a, b))

    def choice(self, options):
        if self.data is None:
            return options[self.rng.integers(len(options))]
        return self.data.draw(st.sampled_from(options))


def _volts(P):
    return P[lo.VLIM] if math.isfinite(P[lo.VLIM]) else 10.0


def _current_scale(P):
    return P[lo.ILIM] if math.isfinite(P[lo.ILIM]) else _volts(P) / P[lo.R]


def _ratio(model, P):
    """|N(q0)|: motor rad per output rad (or m)."""
    return abs(rhs_reference.row_at(P, model.T, lo.T_N, model.q0)[0])


def _speed_scale(model, P):
    """The output's no-load speed at the voltage limit (rad/s, or m/s)."""
    return _volts(P) / P[lo.KE] / _ratio(model, P)


def _torque_scale(model, P):
    """The motor's torque at the current limit, at the output (N*m, or N)."""
    return _ratio(model, P) * P[lo.KT] * _current_scale(P)


def _segments(model, P):
    """Each compliance's half play and stiffness at q0, motor side first."""
    T, q0, ks = model.T, model.q0, P[lo.KSCALE]
    if model.rigid:
        return [(0.0, math.inf)]
    out = [(P[lo.HALF_PLAY], ks * rhs_reference.row_at(P, T, lo.T_K, q0)[0])]
    g = int(P[lo.OFF_SEG])
    for j in range(1, int(P[lo.NMID]) + 1):
        k = ks * rhs_reference.row_at(P, T, lo.T_KS + 2 * (j - 1), q0)[0]
        out.append((P[g + lo.SEG_STRIDE * j + lo.SEG_PLAY], k))
    return out


def _scaled(draw, scale, spread=1.2):
    return scale * draw.uniform(-spread, spread)


def _deflection(draw, c, z):
    """A deflection across the play's edges: anywhere from beyond the play on one side to
    the other, just at an edge, or within a hair of it."""
    kind = draw.choice(("across", "edge", "near edge", "inside"))
    side = draw.choice((-1.0, 1.0))
    if kind == "across":
        return draw.uniform(-(c + 3 * z), c + 3 * z)
    if kind == "edge":
        return side * c
    if kind == "near edge":
        return side * (c + draw.uniform(-1e-3, 1e-3) * max(c, z))
    return draw.uniform(-c, c)


def _rate(draw, previous, scale):
    """A node's rate: 0 (at rest), the neighbour's less a small difference, or any."""
    kind = draw.choice(("rest", "near", "any"))
    if kind == "rest":
        return 0.0
    if kind == "near":
        return previous - _scaled(draw, 0.05 * scale)
    return _scaled(draw, scale, 1.5)


def _draw_state(draw, model, P):
    x = np.zeros(model.nx)
    lo_s, hi_s = model.stroke
    span = hi_s - lo_s
    at_end = P[lo.STROKE_MODE] == lo.STROKE_STOP and draw.choice((True, False))
    if P[lo.PERIODIC] > 0:
        p = draw.uniform(lo_s - span, hi_s + span)
    elif at_end:  # at an end of the stroke, or into its stop
        p = draw.choice((lo_s, hi_s)) + draw.uniform(-0.01, 0.01) * span
    else:
        p = draw.uniform(lo_s, hi_s)
    w = _speed_scale(model, P)
    pd = _rate(draw, 0.0, w)
    torque = _torque_scale(model, P) + abs(P[lo.HINGE_M])
    # the chain from the motor side to the load: each segment's deflection across its play
    positions, rates = [p], [pd]
    for c, k in _segments(model, P):
        z = torque / k if math.isfinite(k) else 1e-3 * span
        positions.append(positions[-1] - _deflection(draw, c, z))
        rates.append(_rate(draw, rates[-1], w))
    x[0], x[1], x[2], x[3] = p, pd, positions[-1], rates[-1]
    if at_end:  # the load leaving the stop at up to twice the speed at which the stop's damper would pull
        load = 0 if model.rigid else 2
        end = hi_s if x[load] > 0.5 * (lo_s + hi_s) else lo_s
        x[load + 1] = -P[lo.KSTOP] * (x[load] - end) / P[lo.DSTOP] * draw.uniform(0.0, 2.0)
    nm, o = int(P[lo.NMID]), int(P[lo.OFF_NODE])
    for j in range(nm):
        x[o + 2 * j], x[o + 2 * j + 1] = positions[j + 1], rates[j + 1]
    x[4] = _scaled(draw, _current_scale(P))
    x[5] = _scaled(draw, _volts(P), 1.5)
    c0 = P[lo.HALF_PLAY]  # the play operator's output: at an edge of the play, or inside it
    x[6] = p - (draw.choice((-c0, c0)) if draw.choice((True, False)) else draw.uniform(-c0, c0))
    nc, oc = int(P[lo.NC]), int(P[lo.OFF_C])
    for j in range(nc):
        gain = abs(P[oc + j])
        x[lo.NX_PHYS + j] = _scaled(draw, _current_scale(P) / gain if gain > 0 else 1.0, 1.5)
    for j in range(lo.NX_PHYS + nc, o if nm else model.nx):  # speed-estimator states: held
        x[j] = _scaled(draw, 1.0)
    return x


def _draw_example(draw, name, model, params):
    """One example of a case: its parameters (with the scratch slots a switch location sets,
    the held sliding directions and the breakaway gauges), state, time and held current."""
    P = params[draw.choice(range(len(params)))]
    if P[lo.STICK] > 0 and "switch" in CASES[name].slots:
        P = P.copy()
        P[lo.DIR_M] = draw.choice((0.0, 0.0, 1.0, -1.0))
        P[lo.DIR_L] = draw.choice((0.0, 0.0, 1.0, -1.0))
        P[lo.HOLD_GAUGE] = draw.choice((0.0, 0.0, 1.0, 2.0))
    x = _draw_state(draw, model, P)
    t = draw.uniform(0.0, 2.0) if draw.choice((True, False)) else draw.uniform(0.1, 0.5)  # the commands' transients
    if P[lo.CMODE] == lo.CONTINUOUS and draw.choice((True, False)):
        _within_the_limit(draw, model, P, x, t)
    return P, x, t, _scaled(draw, _current_scale(P))


def _within_the_limit(draw, model, P, x, t):
    """Set the continuous motion controller's state with the largest output gain so that the
    current reference, its output plus the feedforward current, lies within the current
    limit (the loop tracking, not clamped: where every term of the feedforward shows)."""
    nc, oc, od = int(P[lo.NC]), int(P[lo.OFF_C]), int(P[lo.OFF_D])
    gains = [abs(P[oc + j]) for j in range(nc)]
    if not nc or max(gains) == 0.0:
        return
    j = gains.index(max(gains))
    r, i_ff, w_ff = rhs_reference.continuous_command(t, P, model.T)
    u = (r, x[2], rhs_reference.row_at(P, model.T, lo.T_N, x[0])[0] * x[1] - w_ff)
    others = sum(P[od + m] * u[m] for m in range(3)) + sum(P[oc + k] * x[lo.NX_PHYS + k] for k in range(nc) if k != j)
    x[lo.NX_PHYS + j] = (_scaled(draw, _current_scale(P), 0.8) - i_ff - others) / P[oc + j]


def _full_scale(name, model, params, n=64):
    """The largest magnitude of each result of the transcription over n seeded examples of
    the case."""
    draw = Draws(rng=np.random.default_rng(0))
    return np.max([np.abs(_transcribed(t, x, P, model.T, iref))
                   for P, x, t, iref in (_draw_example(draw, name, model, params) for _ in range(n))], axis=0)


# --- the comparison -------------------------------------------------------------------------

def _transcribed(t, x, P, T, iref):
    dx, aux = np.zeros(x.size), np.zeros(lo.NAUX)
    rhs_reference.rhs(t, x, P, T, iref, dx, aux)
    return np.concatenate([dx, aux])


def _compiled(t, x, P, T, iref):
    dx, aux = np.full(x.size, np.nan), np.full(lo.NAUX, np.nan)
    compiled_rhs(t, x, P, T, iref, dx, aux)
    return np.concatenate([dx, aux])


def _sensitivity(t, x, P, T, iref, out):
    """sum_j |d out / d u_j| |u_j| over u = (t, x, i_ref held), by one-sided differences."""
    total = np.zeros_like(out)
    for j in range(x.size):
        if x[j] != 0.0:
            y = x.copy()
            y[j] += STEP * abs(x[j])
            total += np.abs(_transcribed(t, y, P, T, iref) - out)
    if t != 0.0:
        total += np.abs(_transcribed(t + STEP * abs(t), x, P, T, iref) - out)
    if iref != 0.0:
        total += np.abs(_transcribed(t, x, P, T, iref + STEP * abs(iref)) - out)
    return total / STEP


def _tolerance(t, x, P, T, iref, out, scale):
    """RTOL of the result and of its full scale, plus SENSITIVITY_ULPS eps of its sensitivity."""
    return RTOL * (np.abs(out) + scale) + SENSITIVITY_ULPS * EPS * _sensitivity(t, x, P, T, iref, out)


def _compare(t, x, P, T, iref, scale):
    """The transcription's results, the compiled ones and the tolerance."""
    want = _transcribed(t, x, P, T, iref)
    got = _compiled(t, x, P, T, iref)
    return want, got, _tolerance(t, x, P, T, iref, want, scale)


@pytest.mark.parametrize("name", list(CASES))
@settings(max_examples=EXAMPLES, deadline=None)
@given(data=st.data())
def test_compiled_rhs_equals_the_transcription(built, name, data):
    """dx and aux of the compiled right-hand side equal the transcription's within the
    tolerance at any drawn state, time and held current of the case."""
    model, params, scale = built(name)
    P, x, t, iref = _draw_example(Draws(data), name, model, params)
    want, got, tol = _compare(t, x, P, model.T, iref, scale)
    assert np.all(np.isfinite(want)), want
    bad = np.abs(got - want) > tol
    assert not np.any(bad), (f"{name}: differ at {np.flatnonzero(bad)} "
                             f"(x {x.tolist()}, t {t!r}, iref {iref!r}): {got[bad]} vs {want[bad]}, tol {tol[bad]}")


TIMED = [name for name, case in CASES.items() if case.refs != "sine"]


@pytest.mark.parametrize("name", TIMED)
def test_compiled_rhs_equals_the_transcription_along_each_command(built, name):
    """Every command of a continuous or open loop, along its time line (the commands'
    transients, the move's every segment, the table's cells, the shaper's impulses): at the
    start's equilibrium with the motion controller tracking (its output within the current
    limit, so the feedforward's every term shows), every 7.5 ms over 1.2 s."""
    model, params, scale = built(name)
    draw = Draws(rng=np.random.default_rng(1))
    for P in params:
        x0 = initial_state(model, P)
        for t in np.linspace(0.0, 1.2, 161):
            x = x0.copy()
            if P[lo.CMODE] == lo.CONTINUOUS:
                _within_the_limit(draw, model, P, x, t)
            want, got, tol = _compare(t, x, P, model.T, 0.0, scale)
            bad = np.abs(got - want) > tol
            assert not np.any(bad), f"{name}, t = {t}: {got[bad]} vs {want[bad]} (tol {tol[bad]})"


def test_the_cases_cover_every_branch_kind(built):
    """The cases build what they claim: rigid, cam, two-mass with and without play, the full
    chain, each controller mode, friction that holds, the lossy blend's both forms."""
    def slot(name, s, i=0):
        return built(name)[1][i][s]
    assert slot("ema two-mass sampled smooth", lo.RIGID) == 0 and slot("ema two-mass sampled smooth", lo.HALF_PLAY) > 0
    assert slot("ema two-mass no play, constant inertia, lossless, end stop", lo.HALF_PLAY) == 0
    assert slot("ema full chain sampled smooth", lo.NMID) >= 2
    assert slot("ema full chain sampled stick, end stop (slots)", lo.NODE_FRIC, 2) > 0
    assert slot("cam rigid periodic smooth", lo.CAM) > 0 and slot("cam rigid periodic smooth", lo.PERIODIC) > 0
    assert slot("cam rigid periodic smooth", lo.L) == 0
    assert slot("emps rigid sampled stick (slots)", lo.STICK) == 1 and slot("emps rigid sampled smooth", lo.RIGID) == 1
    assert slot("ema two-mass open loop", lo.CMODE) == lo.OPEN_LOOP
    assert slot("ema two-mass sampled smooth", lo.CMODE) == lo.SAMPLED
    assert slot("ema two-mass continuous, feedforward, shaper (slots)", lo.CMODE) == lo.CONTINUOUS
    assert slot("ema two-mass continuous, feedforward, shaper (slots)", lo.SHAPE_A0) > 0
    assert slot("ema two-mass continuous, feedforward, shaper (slots)", lo.FF_MODEL) == 1
    kinds = {int(P[lo.REF_KIND]) for P in built("ema two-mass continuous, feedforward, shaper (slots)")[1]}
    assert kinds == {lo.REF_CONST, lo.REF_SINE, lo.REF_STEP, lo.REF_RAMP, lo.REF_MOVE, lo.REF_TABLE}
    near = built("ema rigid near self-locking, open loop, stick")[1][0]
    assert near[lo.ETA_MEAN] < 2 * abs(near[lo.ETA_HALF])  # the rounded |sg| blend
    ema = built("ema two-mass sampled smooth")[1][0]
    assert 0 < ema[lo.ETA_MEAN] and ema[lo.ETA_MEAN] >= 2 * abs(ema[lo.ETA_HALF])  # the quadratic blend


@pytest.mark.parametrize("slot, error", [("KSCALE", 1e-9), ("ETA_MEAN", 1e-9), ("ETA_HALF", 1e-9), ("JW", 1e-9),
                                         ("KT", 1e-9), ("KE", 1e-9), ("HINGE_M", 1e-9), ("KAW", 1e-9),
                                         ("INV_L", 1e-9), ("HALF_PLAY", 1e-6), ("BETA", 1e-6), ("TC", 1e-6)])
def test_a_small_error_in_a_parameter_fails_the_comparison(built, slot, error):
    """The tolerance is tight: the compiled right-hand side with one parameter off by a part
    in 1e9 (1e6 for the play, the damper and the Coulomb friction, whose terms are a
    thousandth of the deflection's, the spring's and the motor torque's here) differs from
    the transcription beyond it, at a loaded, moving state with the voltage clamped (the
    back-calculation acting)."""
    model, params, scale = built("ema two-mass sampled smooth")
    P = params[0]
    x = initial_state(model, P)
    x[1], x[3] = 0.3, 0.25
    x[4], x[5] = 0.8 * P[lo.ILIM], 1.2 * P[lo.VLIM]  # the PI's output beyond the voltage limit
    t, iref = 0.1, 0.9 * P[lo.ILIM]
    want, got, tol = _compare(t, x, P, model.T, iref, scale)
    assert np.all(np.abs(got - want) <= tol)
    wrong = P.copy()
    wrong[getattr(lo, slot)] *= 1.0 + error
    assert np.any(np.abs(_compiled(t, x, wrong, model.T, iref) - want) > tol)
