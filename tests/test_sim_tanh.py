"""The kernel's friction tanh skips the library call only where tanh rounds to +-1."""

import math

import numpy as np

from servo_toolkit.sim.kernel import TANH_ONE, tanh


def test_tanh_equals_math_tanh_bit_for_bit():
    a = np.concatenate([np.linspace(-40.0, 40.0, 4001), [0.0, -0.0, 1e-300, 18.0, 19.5, 21.999999, 22.0]])
    for v in np.concatenate([a, -a]):
        assert tanh(float(v)) == math.tanh(float(v))
        assert math.copysign(1.0, tanh(float(v))) == math.copysign(1.0, math.tanh(float(v)))


def test_cut_off_is_where_tanh_is_one_in_double():
    # 1 - tanh(a) = 2 exp(-2 a) / (1 + exp(-2 a)) is below half an ulp of 1 from a = 19.06
    assert 2.0 * math.exp(-2.0 * TANH_ONE) < 2.0 ** -54
    assert tanh(math.inf) == 1.0 and tanh(-math.inf) == -1.0
    assert math.isnan(tanh(math.nan))
