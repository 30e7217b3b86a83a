"""The compiled commands, feedforward and controller (servo_toolkit/_physics: command.h,
feedforward.h, control.h) on the models of tests/test_rhs_transcription.py plus the sampled
loop with each speed estimator and with a gain schedule, at seeded random times and states:
the commands, the references through the shaper and the continuous controller's feedforward
equal their transcription (tests/rhs_reference.py, rhs_reference_command.py), and every
function reads its parameters and tables only (read-only arrays, left unchanged).

Agreement: the kernels are compiled with fast-math (reassociated sums, fused multiply-adds,
reciprocals for divisions) and their own smooth sign (within 1 ulp of the C library's tanh,
which the transcription calls), so a sum or a product may round differently in its last
bits. A result is compared to a relative 1e-12 of its full scale: the largest magnitude that
result takes over the case's examples (the feedforward's inverse dynamics are a sum of terms
that cancel the hinge moment).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit._physics import _kernels as C
from servo_toolkit.sim import ModelOptions
from servo_toolkit.sim import layout as lo

from . import rhs_reference, rhs_reference_command
from .test_rhs_transcription import CASES, TWO, Case, Draws, _draw_state, case_builder

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
    return case_builder(ema, ALL, full_scale=False)


def _examples(model, params, seed):
    draw = Draws(rng=np.random.default_rng(seed))
    rng = np.random.default_rng(seed + 1)
    for P in params:
        for _ in range(EXAMPLES):
            x = _draw_state(draw, model, P)
            t = draw.uniform(0.0, 2.0) if draw.choice((True, False)) else draw.uniform(0.1, 0.5)
            if rng.random() < 0.1:  # a time exactly at a command's start (the step's edge)
                t = float(P[lo.REF_T0])
            yield P, x, t, (x[2] + rng.normal(0, 0.01), x[2], x[1] * rng.normal(0, 10.0))


def _commands(impl, t, P, T):
    """The commands, the reference and the continuous controller's command and feedforward at
    t, through the compiled kernels (``C``) or the transcription (None), in a flat list."""
    ref, cmd = rhs_reference, rhs_reference_command
    kind = int(P[lo.REF_KIND])
    # a move is a reference only (the kernels' command of a move is its offset)
    out = [] if kind == lo.REF_MOVE else [(impl or cmd).command(t, P)]
    out += [(impl or cmd).reference(t, P), *(impl or ref).continuous_command(t, P, T)]
    if kind == lo.REF_TABLE:
        out += (impl or cmd).table_rates(t, P)
    if kind == lo.REF_MOVE:
        out += (impl or cmd).move_rates(t, P)
    return out


def _calls(t, x, P, T, inputs):
    """Every compiled function of the controller at (t, x), on copies of x and its scratch."""
    out = [C.command(t, P), C.reference(t, P), *C.schedule_factors(P, x[2]), *C.feedforward(t, P, T),
           *C.continuous_command(t, P, T), C.motor_angle(P, T, x[0]), C.measured_angle(x[2], P),
           C.measured_motor_angle(P, T, x[0])]
    if int(P[lo.CMODE]) == lo.OPEN_LOOP:
        return out
    nc = int(P[lo.NC])
    r, th, wm = inputs
    for write in (False, True):
        dx = np.zeros(x.size)
        out.append(C.motion(x, P, r, th, wm, dx, lo.NX_PHYS, write))
        out += dx[lo.NX_PHYS:lo.NX_PHYS + nc].tolist()
    xs, work = x.copy(), np.zeros(max(nc, 1))
    out.append(C.controller_sample(t, xs, P, T, work))
    for i_ff in (0.0, 0.3 * P[lo.ILIM], 3.0 * P[lo.ILIM], -3.0 * P[lo.ILIM]):
        xs, work = x.copy(), np.zeros(max(nc, 1))
        out.append(C.controller_update(r, xs, P, T, work, i_ff, 0.1 * wm))
    return out


@pytest.mark.parametrize("name", list(ALL))
def test_commands_and_feedforward_are_their_transcription(built, name):
    """The command (the open loop's: every kind but the move), the reference through the
    shaper, the sampled table's and the move's rates and the continuous controller's
    (r, i_ff, w_ff), at seeded times of every parameter variant
    of the case: within RTOL of each result's full scale, NaN where the transcription's is."""
    model, params = built(name)
    want, got = [], []
    for P, x, t, inputs in _examples(model, params, seed=sum(map(ord, name))):
        want.append(_commands(None, t, P, model.T))
        got.append(_commands(C, t, P, model.T))
    groups = {}
    for a, b in zip(want, got):
        groups.setdefault(len(a), []).append((a, b))
    for rows in groups.values():
        a, b = np.array([r[0] for r in rows], float), np.array([r[1] for r in rows], float)
        assert np.array_equal(np.isnan(a), np.isnan(b))
        a, b = np.nan_to_num(a), np.nan_to_num(b)
        scale = np.max(np.abs(a), axis=0)
        assert np.all(np.abs(a - b) <= RTOL * scale), (name, np.max(np.abs(a - b) / np.maximum(scale, 1e-300)))


@pytest.mark.parametrize("name", list(ALL))
def test_the_controller_reads_its_parameters_only(built, name):
    """Every compiled function of the controller, the commands and the feedforward takes
    read-only parameters and tables, leaves them unchanged, and gives the same results as on
    writable copies."""
    model, params = built(name)
    for P, x, t, inputs in list(_examples(model, params, seed=sum(map(ord, name))))[::4]:
        P_ro, T_ro = P.copy(), model.T.copy()
        P_ro.flags.writeable = T_ro.flags.writeable = False
        got = _calls(t, x.copy(), P_ro, T_ro, inputs)
        assert np.array_equal(P_ro, P) and np.array_equal(T_ro, model.T)
        want = _calls(t, x.copy(), P.copy(), model.T.copy(), inputs)
        assert np.array_equal(np.array(got, float), np.array(want, float), equal_nan=True)


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


@pytest.mark.parametrize("slot", ["REF_A", "REF_F", "FF_JSCALE"])
def test_a_small_error_fails_the_comparison(built, slot):
    """The comparison is tight: the compiled kernels with the command's amplitude or
    frequency or the feedforward's inertia scale off by a part in 1e9 differ from the
    transcription beyond it."""
    model, params = built("ema two-mass continuous, feedforward, shaper (slots)")
    sine = [P for P in params if P[lo.REF_KIND] == lo.REF_SINE][:1]
    want, got = [], []
    for P, x, t, inputs in _examples(model, sine, seed=3):
        wrong = P.copy()
        wrong[getattr(lo, slot)] *= 1.0 + 1e-9
        want.append(_commands(None, t, P, model.T))
        got.append(_commands(C, t, wrong, model.T))
    a, b = np.array(want, float), np.array(got, float)
    assert np.any(np.abs(a - b) > RTOL * np.max(np.abs(a), axis=0))
