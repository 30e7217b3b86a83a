"""The C controller, commands and feedforward (servo_toolkit/_physics: command.h,
feedforward.h, control.h) equal the numba kernels they replace (servo_toolkit.sim.kernel,
command_kernel, table_kernel, feedforward_kernel) on the models of
tests/test_rhs_transcription.py, plus the sampled loop with each speed estimator and with a
gain schedule, at seeded random times and states.

Agreement: the C is the numba code's operations in their order, but numba compiled it with
fast-math flags (reassociated sums, fused multiply-adds, reciprocals for divisions) and the C
is compiled without them, so a sum or a product may round differently in its last bits. A
result is compared to a relative 1e-12 of its full scale: the largest magnitude of the terms
it is a sum of (the controller's output is a sum of terms that cancel while the loop tracks;
the feedforward's inverse dynamics cancel the hinge moment), approximated by the largest
magnitude that result takes over the case's examples. Integer-valued and selected results
(the commands' held values, the encoders' counts, the shaper's and the schedule's choices)
are the same operations and agree to the last bit in practice; the test reports how many
agree exactly.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit._physics import _kernels as C
from servo_toolkit.loop.schedule import gain_schedule
from servo_toolkit.sim import ModelOptions, build_model
from servo_toolkit.sim import command_kernel, feedforward_kernel, kernel, table_kernel
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.reference import fill

from .test_rhs_transcription import CASES, FF, TWO, Case, Draws, _draw_state, _references, _scene, _with_slots

RTOL = 1e-12
#: examples drawn per parameter variant of a case
EXAMPLES = 40

#: the transcription's cases, and the sampled loop's speed estimators and gain schedule
EXTRA = {
    "ema two-mass sampled, difference estimator": Case("ema_reference", "designed",
                                                       replace(TWO, speed_estimator="difference"), refs="all"),
    "ema two-mass sampled, kalman estimator, feedforward": Case(
        "ema_reference", "designed+ff", replace(TWO, speed_estimator="kalman"), refs="all"),
    "ema rigid sampled, kalman estimator, unquantized": Case(
        "ema_reference", "designed", ModelOptions(compliance=False, speed_estimator="kalman", quantization=False),
        refs="moves"),
    "ema two-mass sampled, gain schedule, shaper": Case("ema_reference", "designed+schedule+shaper", TWO,
                                                        refs="all"),
    "ema two-mass sampled, gain schedule, feedforward": Case("ema_reference", "designed+schedule+ff", TWO,
                                                             refs="all"),
}
ALL = {**CASES, **EXTRA}


@pytest.fixture(scope="module")
def built(ema):
    """``built(case)``: ``(model, parameter variants)`` of a case, built once for the module."""
    from servo_toolkit.loop.default_controller import default_controller
    from servo_toolkit.loop.shaper import InputShaper
    from servo_toolkit.sim import controller_for

    scenes = {"ema_reference": (ema[0], {"designed": ema[1]})}
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
            case = ALL[name]
            if case.scene not in scenes:
                scenes[case.scene] = _scene(case.scene), {}
            ctrl = None if case.controller is None else controller(case.scene, case.controller)
            model = build_model(scenes[case.scene][0], ctrl, case.options)
            params = [p for ref in _references(model, case.refs)
                      for p in _with_slots(model, fill(model, ref), case.slots)]
            cases[name] = model, params
        return cases[name]

    return get


def _results(impl, t, x, P, T, rng):
    """Every function's results at (t, x) through ``impl`` (``"c"`` or ``"numba"``), in a flat
    list; the controller sample's on copies of x and its scratch."""
    c = impl == "c"
    kind = int(P[lo.REF_KIND])
    out = [
        (C.command if c else command_kernel.command)(t, P),
        (C.reference if c else command_kernel.reference)(t, P),
        *(C.schedule_factors if c else command_kernel.schedule_factors)(P, x[2]),
        *(C.feedforward if c else feedforward_kernel.feedforward)(t, P, T),
        *(C.continuous_command if c else kernel.continuous_command)(t, P, T),
        (C.motor_angle if c else kernel.motor_angle)(P, T, x[0]),
        (C.measured_angle if c else kernel.measured_angle)(x[2], P),
        (C.measured_motor_angle if c else kernel.measured_motor_angle)(P, T, x[0]),
    ]
    if kind == lo.REF_TABLE:
        out += (C.table_rates if c else table_kernel.table_rates)(t, P)
    if kind == lo.REF_MOVE:
        out += (C.move_rates if c else command_kernel.move_rates)(t, P)
    if int(P[lo.CMODE]) == lo.OPEN_LOOP:
        return out
    nc = int(P[lo.NC])
    r, th, wm = rng
    for write in (False, True):
        dx = np.zeros(x.size)
        out.append((C.motion if c else kernel._motion)(x, P, r, th, wm, dx, lo.NX_PHYS, write))
        out += dx[lo.NX_PHYS:lo.NX_PHYS + nc].tolist()
    xs, work = x.copy(), np.zeros(max(nc, 1))
    out.append((C.controller_sample if c else kernel.controller_sample)(t, xs, P, T, work))
    out += xs.tolist() + work[:nc].tolist()
    # a given reference with a feedforward current that drives the output into the clamp
    # (the back-calculation) or not, and a feedforward speed
    for i_ff in (0.0, 0.3 * P[lo.ILIM], 3.0 * P[lo.ILIM], -3.0 * P[lo.ILIM]):
        xs, work = x.copy(), np.zeros(max(nc, 1))
        out.append((C.controller_update if c else kernel.controller_update)(r, xs, P, T, work, i_ff, 0.1 * wm))
        out += xs.tolist() + work[:nc].tolist()
    return out


def _examples(model, params, seed):
    draw = Draws(rng=np.random.default_rng(seed))
    rng = np.random.default_rng(seed + 1)
    for P in params:
        for _ in range(EXAMPLES):
            x = _draw_state(draw, model, P)
            t = draw.uniform(0.0, 2.0) if draw.choice((True, False)) else draw.uniform(0.1, 0.5)
            if rng.random() < 0.1:  # a time exactly at a command's start (the step's edge)
                t = float(P[lo.REF_T0])
            inputs = (x[2] + rng.normal(0, 0.01), x[2], x[1] * rng.normal(0, 10.0))
            yield P, x, t, inputs


@pytest.mark.parametrize("name", list(ALL))
def test_c_equals_numba(built, name):
    """Every ported function, C against numba, at seeded states and times of every parameter
    variant of the case (references, slots)."""
    model, params = built(name)
    want, got = [], []
    for P, x, t, inputs in _examples(model, params, seed=sum(map(ord, name))):
        Pr = P.copy()
        Pr.flags.writeable = False  # the C only reads P and T
        a = _results("numba", t, x.copy(), P, model.T, inputs)
        b = _results("c", t, x.copy(), Pr, model.T, inputs)
        assert len(a) == len(b)
        want.append(a)
        got.append(b)
    for a, b in zip(want, got):
        assert np.array_equal(np.isnan(a), np.isnan(b))
    diff = _max_differences(want, got)
    print(f"\n{name}: {diff}")
    assert diff["worst"] <= RTOL, (name, diff)


def _max_differences(want, got):
    """The largest difference relative to the full scale (the largest finite magnitude of
    that result over the examples), over results of one position in the flat lists (lists
    of one length per parameter variant: grouped by length); a non-finite result (an
    infinite current limit's clamp) must be the same value in both."""
    worst, exact, total = 0.0, 0, 0
    groups = {}
    for a, b in zip(want, got):
        groups.setdefault(len(a), []).append((a, b))
    for rows in groups.values():
        a = np.array([r[0] for r in rows], float)
        b = np.array([r[1] for r in rows], float)
        same = (a == b) | (np.isnan(a) & np.isnan(b))
        finite = np.isfinite(a) & np.isfinite(b)
        assert np.all(same | finite), "a non-finite result differs"
        scale = np.max(np.where(np.isfinite(a), np.abs(a), 0.0), axis=0)
        scale[scale == 0.0] = 1.0
        with np.errstate(invalid="ignore"):  # inf - inf where both are the same infinity
            d = np.where(same, 0.0, np.abs(np.where(finite, a - b, 0.0))) / scale
        worst = max(worst, float(np.max(d)))
        exact += int(np.sum(same))
        total += a.size
    return {"worst": worst, "exact": exact, "total": total}


def test_a_small_error_fails_the_comparison(built):
    """The comparison is tight: the C at a command amplitude, a controller gain or the
    feedforward's inertia scale off by a part in 1e9 differs from the numba beyond it."""
    model, params = built("ema two-mass continuous, feedforward, shaper (slots)")
    sine = [P for P in params if P[lo.REF_KIND] == lo.REF_SINE][:1]
    for slot in (lo.REF_A, int(sine[0][lo.OFF_C]), lo.FF_JSCALE):
        want, got = [], []
        for P, x, t, inputs in _examples(model, sine, seed=3):
            wrong = P.copy()
            wrong[slot] *= 1.0 + 1e-9
            want.append(_results("numba", t, x.copy(), P, model.T, inputs))
            got.append(_results("c", t, x.copy(), wrong, model.T, inputs))
        assert _max_differences(want, got)["worst"] > RTOL, slot


def test_the_extra_cases_build_what_they_claim(built):
    def slot(name, s):
        return built(name)[1][0][s]
    assert slot("ema two-mass sampled, difference estimator", lo.EST) == lo.EST_DIFFERENCE
    assert slot("ema two-mass sampled, kalman estimator, feedforward", lo.EST) == lo.EST_KALMAN
    assert slot("ema two-mass sampled, kalman estimator, feedforward", lo.FF_ON) == 1
    assert slot("ema two-mass sampled, gain schedule, shaper", lo.SCHED) > 0
    assert slot("ema two-mass sampled, gain schedule, shaper", lo.SHAPE_A0) > 0
    assert slot("ema two-mass sampled smooth", lo.AW) > 0  # the sampled controller's back-calculation
    assert slot("ema two-mass continuous, feedforward, shaper (slots)", lo.AW) > 0
    assert slot("ema two-mass sampled smooth", lo.LSB) > 0 and slot("ema two-mass sampled smooth", lo.LSB_M) >= 0
