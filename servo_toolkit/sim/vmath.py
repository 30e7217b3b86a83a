"""Branch-free elementary functions for the compiled right-hand side.

A library call (``math.tanh``) inside a loop keeps LLVM from vectorizing it: the batched
kernel (:mod:`.batch_lanes`) advances several variants in lockstep in one SIMD loop, so the
one right-hand side (:func:`.kernel.rhs_phys`), which the single run shares, uses these
instead. They are plain arithmetic (no calls; in a vectorized loop LLVM turns their
branches into selects), inlined at numba-IR level, and as accurate as the C library's: :func:`tanh` is within 1 ulp of ``math.tanh``
(the C library's own bound is 2 ulp; tests/test_sim_tanh.py measures both against a
50-digit reference).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..core.jit_cache import install as _install_cache

_install_cache()  # noqa: E402 - before any kernel below is decorated

#: numba fast-math flags that keep NaN/inf semantics (non-finite detection must work); the
#: whole right-hand side (:mod:`.kernel`) is compiled with them
FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}
#: helpers are inlined at numba-IR level: no call overhead, no array reference counting
inline = nb.njit(cache=True, fastmath=FASTMATH, error_model="numpy", inline="always")

#: |a| from which tanh(a) rounds to +-1 in double precision (1 - tanh(22) = 1.6e-19; libm's
#: own cut-off)
TANH_ONE = 22.0
#: below this |a| the rational form, above it 1 - 2 / (exp(2 |a|) + 1)
TANH_SMALL = 0.625
# Cephes' tanh rational approximation on |a| < 0.625: tanh a = a + a^3 P(a^2) / Q(a^2)
_P0, _P1, _P2 = -9.64399179425052238628e-1, -9.92877231001918586564e1, -1.61468768441708447952e3
_Q0, _Q1, _Q2 = 1.12811678491632931402e2, 2.23548839060100448583e3, 4.84406305325125486048e3
# Cody-Waite split of ln 2 (the high part has trailing zero bits, so n * LN2_HI is exact)
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.44269504088896338700e+00
#: 2^n for the exponent range of exp(2 |a|), |a| < TANH_ONE (a table gather vectorizes;
#: building the exponent bits does not, in numba)
_POW2 = np.ldexp(1.0, np.arange(66)).astype(np.float64)
#: 2^-n for the same range (exp(-y) without a division)
_POW2_NEG = np.ldexp(1.0, -np.arange(66)).astype(np.float64)


@inline
def exp_pos(y):
    """exp(y) for 0 <= y <= 2 TANH_ONE (within 1 ulp; NaN passes through).

    y = n ln 2 + r with |r| <= ln 2 / 2, exp(r) by its Taylor polynomial to r^13 (truncation
    below 1e-17 relative), times 2^n from a table.
    """
    yc = min(max(y, 0.0), 2.0 * TANH_ONE)  # NaN: the table index below stays in range
    n = math.floor(yc * _INV_LN2 + 0.5)
    r = (y - n * _LN2_HI) - n * _LN2_LO
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    p = p * r * r + r  # exp(r) - 1, added to 1 last to keep its low bits
    return (1.0 + p) * _POW2[int(n)]


@inline
def exp_neg(y):
    """exp(-y) for 0 <= y <= 2 TANH_ONE (within 1 ulp; NaN passes through): as
    :func:`exp_pos`, with -r and 2^-n (no division, which costs a vectorized loop more than
    the polynomial)."""
    yc = min(max(y, 0.0), 2.0 * TANH_ONE)
    n = math.floor(yc * _INV_LN2 + 0.5)
    r = (n * _LN2_HI - y) + n * _LN2_LO
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    p = p * r * r + r
    return (1.0 + p) * _POW2_NEG[int(n)]


@inline
def tanh(a):
    """tanh(a) without a library call (within 1 ulp of math.tanh).

    |a| < 0.625: Cephes' rational form; up to 22: 1 - 2 / (exp(2 |a|) + 1); beyond, +-1
    exactly (where tanh rounds to +-1 in double). Odd: tanh(-a) = -tanh(a) exactly; NaN
    passes through, tanh(+-inf) = +-1.
    """
    x = abs(a)
    # the branches only save work in scalar code (a vectorized loop evaluates both sides
    # and selects): the value is the same either way
    if x >= TANH_ONE:
        return math.copysign(1.0, a)
    if x < TANH_SMALL:
        z = x * x
        y = x + x * z * (((_P0 * z + _P1) * z + _P2) / (((z + _Q0) * z + _Q1) * z + _Q2))
    else:
        y = 1.0 - 2.0 / (exp_pos(2.0 * x) + 1.0)
    return math.copysign(y, a)
