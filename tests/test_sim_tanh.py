"""The kernel's friction tanh and Stribeck exponential: branch-free arithmetic (they vectorize
across variants), within 1 ulp of the exact value (math.tanh, the C library's, is within 2),
tanh exactly +-1 from the cut-off where it rounds to +-1, odd, NaN through."""

import math
from decimal import Decimal, localcontext

import numpy as np

from servo_toolkit.sim.kernel import TANH_ONE, TANH_SMALL, exp_neg, speed_sign, tanh


def _exact(a):
    """tanh(a) to 50 digits, rounded to double."""
    with localcontext() as ctx:
        ctx.prec = 50
        x = Decimal(a)
        if abs(x) < Decimal("1e-12"):  # the series; 1 + 2 x is 1 at 50 digits
            return float(x - x ** 3 / 3 + 2 * x ** 5 / 15)
        e = (2 * x).exp()
        return float((e - 1) / (e + 1))


def _points():
    rng = np.random.default_rng(0)
    edges = [TANH_SMALL, TANH_ONE, 1.0, 0.5]
    near = [np.nextafter(e, d) for e in edges for d in (0.0, 50.0)]
    return np.concatenate([np.linspace(-24.0, 24.0, 4801), rng.uniform(-1.0, 1.0, 1500),
                           rng.uniform(-TANH_ONE, TANH_ONE, 1500), np.exp(rng.uniform(-40.0, 1.0, 500)),
                           [0.0, 1e-300, 5e-324, 2.0 ** -28, *edges, *near]])


def test_tanh_within_one_ulp_of_the_exact_value_and_of_math_tanh():
    worst = worst_libm = 0.0
    for v in _points():
        v = float(v)
        exact = _exact(v)
        ulp = math.ulp(exact) if exact != 0.0 else 5e-324
        ours = tanh(v)
        worst = max(worst, abs(ours - exact) / ulp)
        worst_libm = max(worst_libm, abs(math.tanh(v) - exact) / ulp)
        assert abs(ours - math.tanh(v)) <= 2.0 * math.ulp(math.tanh(v)) or ours == math.tanh(v)
    assert worst <= 1.0 and worst <= worst_libm


def test_tanh_is_odd_and_keeps_the_sign_of_zero():
    for v in _points():
        assert tanh(-float(v)) == -tanh(float(v))
    assert math.copysign(1.0, tanh(-0.0)) == -1.0 and tanh(0.0) == 0.0


def test_cut_off_is_where_tanh_is_one_in_double():
    # 1 - tanh(a) = 2 exp(-2 a) / (1 + exp(-2 a)) is below half an ulp of 1 from a = 19.06
    assert 2.0 * math.exp(-2.0 * TANH_ONE) < 2.0 ** -54
    for a in (19.1, 21.0, np.nextafter(TANH_ONE, 0.0), TANH_ONE, 30.0, 1e300):
        assert tanh(float(a)) == 1.0 == math.tanh(float(a)) and tanh(-float(a)) == -1.0
    assert tanh(math.inf) == 1.0 and tanh(-math.inf) == -1.0
    assert math.isnan(tanh(math.nan))


def test_exp_neg_within_one_ulp_of_the_exact_value():
    """The Stribeck exponential of friction that holds, exp(-y) on 0..44 without a division or
    a library call: within 1 ulp of the 50-digit value; NaN through."""
    rng = np.random.default_rng(1)
    ys = np.concatenate([np.linspace(0.0, 2 * TANH_ONE, 2001), rng.uniform(0.0, 2 * TANH_ONE, 2000),
                         np.exp(rng.uniform(-40.0, 0.0, 300)), [5e-324, math.log(2) / 2, 2 * TANH_ONE]])
    with localcontext() as ctx:
        ctx.prec = 50
        for y in ys:
            exact = float((-Decimal(float(y))).exp())
            assert abs(exp_neg(float(y)) - exact) <= math.ulp(exact), y
    assert math.isnan(exp_neg(math.nan))


def test_the_loss_reads_the_friction_s_smooth_sign_for_either_sign_of_the_ratio():
    """The loss's smooth sign of the output speed, tanh(|N| p' / w_s), is taken from the
    friction's tanh(N p' / w_s) (tanh is odd): the same value for a ratio of either sign."""
    rng = np.random.default_rng(2)
    for n, pd, ws in zip(rng.uniform(-80.0, 80.0, 400), rng.normal(0.0, 2.0, 400), 10.0 ** rng.uniform(-1, 3, 400)):
        n, pd, ws = float(n), float(pd), float(ws)
        assert speed_sign(n, tanh(n * pd * ws)) == tanh(abs(n) * pd * ws)
    assert speed_sign(-3.0, tanh(-3.0 * 0.5)) > 0.0  # a negative ratio, a positive output speed
