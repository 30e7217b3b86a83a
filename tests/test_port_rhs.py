"""The C right-hand side (servo_toolkit/_physics/rhs.h, friction.h, compliance.h) equals the
numba one it replaces (``servo_toolkit.sim.kernel.rhs``) and the plain-Python transcription
(tests/rhs_reference.py), at random states of the 22 model kinds tests/test_rhs_transcription.py
builds (its builders, draws and tolerance are reused here), along each command of the timed
kinds, and the friction and contact laws exactly.

Agreement of the right-hand side: tests/test_rhs_transcription.py's tolerance (its docstring
justifies it: RTOL = 1e-12 of the result and of its full scale, plus 1e3 eps of the result's
sensitivity to its inputs). The C is compiled without fast-math (-std=c99: no contraction into
fused multiply-adds, no reassociation), the numba kernel with it, and the transcription calls
the C library's tanh and exp where both kernels use their own (within 1 ulp): each pair may
round differently in the last bits of every sum, and a sum that cancels (the deflection beyond
the play, a moment against a breakaway level, the continuous controller's output) turns those
bits into a relative difference larger than a few ulps of its result; the operations and
branches are the same, so a logic difference (a wrong law, a wrong branch, a parameter off by
a part in 1e9) is far beyond it (:func:`test_a_small_error_in_a_parameter_fails_the_c_comparison`).
Measured over 300 seeded examples of each case: the C agreed with the transcription to the last
bit in every result of 98-100 % of the examples (the rest within 1e-16 of the full scale, 4e-8
of the tolerance), and with numba within 1.1e-2 of the tolerance (9e-14 of the full scale, the
largest in the full chain and the continuous controller's cancelling sums; 0-70 % of the
examples to the last bit).

The laws (contact, slip_friction, stuck_or_breaking, gear_at_rest) are the same operations in
the same order in both kernels, with no sum that fast-math could contract or reassociate into
another rounding: they agree exactly (slip_friction's Stribeck exponential is exp_neg's
polynomial, whose Horner steps numba may fuse: it is compared exactly where its exponential is
taken, within 1 ulp of the magnitude otherwise; see :func:`test_slip_friction_equals_numba`).
"""

from __future__ import annotations

import math
from unittest.mock import patch

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from servo_toolkit._physics import _kernels as ck
from servo_toolkit.sim import friction_kernel as nf
from servo_toolkit.sim import compliance_kernel as nc
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim import vmath
from servo_toolkit.sim.kernel import rhs as numba_rhs
from servo_toolkit.sim.reference import initial_state

from . import rhs_reference
from .test_rhs_transcription import (CASES, EPS, EXAMPLES, TIMED, Draws, _draw_example, _tolerance, _transcribed,
                                     built)  # noqa: F401 - built: the fixture of the cases' models

# --- the three right-hand sides -------------------------------------------------------------


def _c(t, x, P, T, iref):
    dx, aux = np.full(x.size, np.nan), np.full(lo.NAUX, np.nan)
    ck.rhs(t, x, P, T, iref, dx, aux)
    return np.concatenate([dx, aux])


def _numba(t, x, P, T, iref):
    dx, aux = np.full(x.size, np.nan), np.full(lo.NAUX, np.nan)
    numba_rhs(t, x, P, T, iref, dx, aux)
    return np.concatenate([dx, aux])


def _check(name, t, x, P, T, iref, scale):
    """The C result against the transcription's and numba's, within the transcription test's
    tolerance (measured on the transcription)."""
    want = _transcribed(t, x, P, T, iref)
    assert np.all(np.isfinite(want)), want
    tol = _tolerance(t, x, P, T, iref, want, scale)
    got = _c(t, x, P, T, iref)
    jit = _numba(t, x, P, T, iref)
    where = f"{name} (x {x.tolist()}, t {t!r}, iref {iref!r})"
    bad = np.abs(got - want) > tol
    assert not np.any(bad), f"{where}: C vs transcription at {np.flatnonzero(bad)}: {got[bad]} vs {want[bad]}, tol {tol[bad]}"
    bad = np.abs(got - jit) > tol
    assert not np.any(bad), f"{where}: C vs numba at {np.flatnonzero(bad)}: {got[bad]} vs {jit[bad]}, tol {tol[bad]}"


@pytest.mark.parametrize("name", list(CASES))
@settings(max_examples=EXAMPLES, deadline=None)
@given(data=st.data())
def test_c_rhs_equals_numba_and_the_transcription(built, name, data):
    """dx and aux of the C right-hand side equal numba's and the transcription's at any drawn
    state, time and held current of the case (tests/test_rhs_transcription.py's draws)."""
    model, params, scale = built(name)
    P, x, t, iref = _draw_example(Draws(data), name, model, params)
    _check(name, t, x, P, model.T, iref, scale)


@pytest.mark.parametrize("name", TIMED)
def test_c_rhs_equals_numba_and_the_transcription_along_each_command(built, name):
    """Every command of a continuous or open loop along its time line (as
    tests/test_rhs_transcription.py's), every 15 ms over 1.2 s."""
    from .test_rhs_transcription import _within_the_limit
    model, params, scale = built(name)
    draw = Draws(rng=np.random.default_rng(1))
    for P in params:
        x0 = initial_state(model, P)
        for t in np.linspace(0.0, 1.2, 81):
            x = x0.copy()
            if P[lo.CMODE] == lo.CONTINUOUS:
                _within_the_limit(draw, model, P, x, t)
            _check(name, t, x, P, model.T, 0.0, scale)


@pytest.mark.parametrize("name", list(CASES))
def test_c_rhs_phys_is_rhs(built, name):
    """rhs_phys's ten results are rhs's dx[0:6] and aux, its dx the same intermediate rates
    (the same C, bit for bit), reading read-only arrays."""
    model, params, _ = built(name)
    draw = Draws(rng=np.random.default_rng(2))
    for _ in range(20):
        P, x, t, iref = _draw_example(draw, name, model, params)
        want = _c(t, x, P, model.T, iref)
        dx = np.zeros(x.size)
        P_ro, x_ro, T_ro = P.copy(), x.copy(), model.T.copy()
        for a in (P_ro, x_ro, T_ro):
            a.flags.writeable = False
        out = ck.rhs_phys(t, *x[:lo.NX_PHYS], P_ro, T_ro, iref, x_ro, dx)
        assert len(out) == 10
        assert np.array_equal(np.array(out[:6]), want[:6], equal_nan=True)
        assert list(out[6:]) == [want[x.size + j] for j in (lo.AUX_I, lo.AUX_V, lo.AUX_IREF, lo.AUX_TAU)]
        assert np.array_equal(dx[lo.NX_PHYS:], want[lo.NX_PHYS:x.size])  # held states: left at 0


@pytest.mark.parametrize("slot, error", [("KSCALE", 1e-9), ("ETA_MEAN", 1e-9), ("ETA_HALF", 1e-9), ("JW", 1e-9),
                                         ("KT", 1e-9), ("KE", 1e-9), ("HINGE_M", 1e-9), ("KAW", 1e-9),
                                         ("INV_L", 1e-9), ("HALF_PLAY", 1e-6), ("BETA", 1e-6), ("TC", 1e-6)])
def test_a_small_error_in_a_parameter_fails_the_c_comparison(built, slot, error):
    """tests/test_rhs_transcription.py's check of its tolerance, on the C right-hand side: it
    agrees at a loaded, moving state with the voltage clamped, and one parameter off by a part
    in 1e9 (1e6) fails it."""
    model, params, scale = built("ema two-mass sampled smooth")
    P = params[0]
    x = initial_state(model, P)
    x[1], x[3] = 0.3, 0.25
    x[4], x[5] = 0.8 * P[lo.ILIM], 1.2 * P[lo.VLIM]
    t, iref = 0.1, 0.9 * P[lo.ILIM]
    want = _transcribed(t, x, P, model.T, iref)
    tol = _tolerance(t, x, P, model.T, iref, want, scale)
    assert np.all(np.abs(_c(t, x, P, model.T, iref) - want) <= tol)
    wrong = P.copy()
    wrong[getattr(lo, slot)] *= 1.0 + error
    assert np.any(np.abs(_c(t, x, wrong, model.T, iref) - want) > tol)


def test_the_c_rhs_checks_its_array_sizes(built):
    model, params, _ = built("ema two-mass sampled smooth")
    x = initial_state(model, params[0])
    with pytest.raises(ValueError):
        ck.rhs(0.0, x, params[0], model.T, 0.0, np.zeros(x.size - 1), np.zeros(lo.NAUX))
    with pytest.raises(ValueError):
        ck.rhs(0.0, x, params[0], model.T, 0.0, np.zeros(x.size), np.zeros(lo.NAUX - 1))
    with pytest.raises(ValueError):
        ck.rhs_phys(0.0, *x[:lo.NX_PHYS], params[0], model.T, 0.0, x[:3], np.zeros(3))


# --- the laws, exactly ----------------------------------------------------------------------

#: magnitudes across the scales the right-hand side meets, and the edge values
values = st.one_of(st.floats(-1e6, 1e6, allow_nan=False), st.sampled_from([0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300]))
positive = st.one_of(st.floats(0.0, 1e6), st.sampled_from([0.0, math.inf]))


def _same(a, b):
    """The same double (the sign of a zero aside: numba's nsz flag may flip it), or both NaN."""
    return a == b or (math.isnan(a) and math.isnan(b))


@settings(max_examples=2000, deadline=None)
@given(tau_c=values, tau_d=values)
def test_contact_equals_numba(tau_c, tau_d):
    got = ck.contact(tau_c, tau_d)
    assert got == nc.contact(tau_c, tau_d) == nc.contact.py_func(tau_c, tau_d) == rhs_reference.contact(tau_c, tau_d)


@settings(max_examples=2000, deadline=None)
@given(applied=values, cap=positive)
def test_stuck_or_breaking_equals_numba(applied, cap):
    got = ck.stuck_or_breaking(applied, cap)
    for want in (nf.stuck_or_breaking(applied, cap), nf.stuck_or_breaking.py_func(applied, cap),
                 rhs_reference.stuck_or_breaking(applied, cap)):
        assert _same(got, want)


@settings(max_examples=3000, deadline=None)
@given(torque=values, moment=values, cap_t=positive, cap_m=positive,
       fwd_loss=st.one_of(st.just(0.0), st.floats(0.0, 20.0)), back_loss=st.one_of(st.just(0.0), st.floats(0.0, 1.0)),
       gauge=st.sampled_from([0.0, 1.0, 2.0]))
def test_gear_at_rest_equals_numba(torque, moment, cap_t, cap_m, fwd_loss, back_loss, gauge):
    """Exactly the numba code's own operations (its source run in plain floats) and the
    transcription's; the compiled numba kernel fuses m + loss m into a multiply-add: within
    its rounding of the breakaway distances (and so of the net moment's decision, which is
    the same unless a distance is within that rounding of 0)."""
    args = (torque, moment, cap_t, cap_m, fwd_loss, back_loss, gauge)
    got = ck.gear_at_rest(*args)
    assert _same(got, nf.gear_at_rest.py_func(*args)), args
    assert _same(got, rhs_reference.gear_at_rest(*args)), args
    jit = nf.gear_at_rest(*args)
    if not math.isfinite(cap_t + cap_m):
        assert _same(got, jit) or math.isnan(got) or math.isnan(jit)
        return
    span = 8 * EPS * (abs(torque) + cap_t + (abs(moment) + cap_m) * (1.0 + fwd_loss))
    if gauge > 0.0:
        assert abs(got - jit) <= span, args
    else:
        fwd, bwd = nf.gear_at_rest.py_func(*args[:-1], 1.0), nf.gear_at_rest.py_func(*args[:-1], 2.0)
        near_zero = min(abs(fwd), abs(fwd - bwd)) <= span or abs(bwd) <= span
        assert _same(got, jit) or near_zero, args


@settings(max_examples=3000, deadline=None)
@given(v=st.one_of(st.floats(-1e3, 1e3, allow_nan=False), st.sampled_from([0.0, -0.0, 1e-12, -1e-12])),
       tc=st.floats(0.0, 10.0), drop=st.floats(0.0, 10.0), inv_vs=st.one_of(st.floats(0.0, 1e4), st.just(math.inf)),
       direction=st.sampled_from([0.0, 1.0, -1.0]))
def test_slip_friction_equals_numba(v, tc, drop, inv_vs, direction):
    """Exactly the numba code's own operations (its source and exp_neg's run in plain
    floats); the compiled numba kernel fuses exp_neg's Horner steps and the magnitude's
    multiply-add: within 2 ulp of the breakaway level; the transcription (the C library's exp)
    within 2 ulp too."""
    ts = tc + drop
    args = (v, tc, ts, inv_vs, direction)
    got = ck.slip_friction(*args)
    if math.isnan(v * inv_vs):  # 0 * inf: NaN through every form
        assert math.isnan(got) and math.isnan(nf.slip_friction(*args))
        return
    with patch.object(nf, "exp_neg", vmath.exp_neg.py_func):
        plain = nf.slip_friction.py_func(*args)
    jit = nf.slip_friction(*args)
    ref = rhs_reference.slip_friction(*args)
    assert got == plain, args
    assert abs(got - jit) <= 2 * math.ulp(ts) and abs(got - ref) <= 2 * math.ulp(ts), args
    assert math.copysign(1.0, got) == math.copysign(1.0, jit) == math.copysign(1.0, ref)
