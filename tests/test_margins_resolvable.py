"""Crossings double precision cannot resolve are left out; genuine ones are all kept.

The truth for the genuine crossings is an independent evaluation of the loop: its transfer
function's polynomials (numpy ``polyval``) on a dense grid, sign changes refined by Brent's
method. The truth for the rounding bound is the loop evaluated in exact rational arithmetic
(``fractions``) from the same float64 matrices."""

from __future__ import annotations

import math
import warnings
from fractions import Fraction

import control as ct
import numpy as np
import pytest
from scipy.optimize import brentq

from servo_toolkit.loop.crossings import CROSSING_TOL, EPS, RESOLVABLE_DB, crossings, response_of, rounding_bound
from servo_toolkit.loop.margins import loop_margins

from .conftest import SCENES

warnings.filterwarnings("ignore", module="control")


def _resonant_loop():
    """k / (s (s/p + 1)) * wn^2 / (s^2 + 2 zeta wn s + wn^2): a lightly damped mode whose peak
    (1 / (2 zeta) = 34 dB) lifts |L| through 0 dB twice more after the low-frequency crossover,
    and whose phase drop crosses -180 deg where |L| > 1."""
    k, p, wn, zeta = 2.0, 20.0, 10.0, 0.01
    num = np.array([k * wn**2])
    den = np.polymul(np.polymul([1.0, 0.0], [1 / p, 1.0]), [1.0, 2 * zeta * wn, wn**2])
    return num, den


def _dense_crossings(num, den, lo=1e-3, hi=1e3, points=400_001):
    """Phase and gain crossings (rad/s) of num/den from polyval on a dense grid."""
    def L(w):
        s = 1j * np.asarray(w, float)
        return np.polyval(num, s) / np.polyval(den, s)

    w = np.geomspace(lo, hi, points)
    lw = L(w)
    im, mag = lw.imag, np.log(np.abs(lw))
    wpc = [brentq(lambda x: L(x).imag, w[i], w[i + 1], xtol=1e-14)
           for i in np.nonzero(np.sign(im[:-1]) * np.sign(im[1:]) < 0)[0]]
    wpc = [x for x in wpc if L(x).real < 0]
    wgc = [brentq(lambda x: math.log(abs(L(x))), w[i], w[i + 1], xtol=1e-14)
           for i in np.nonzero(np.sign(mag[:-1]) * np.sign(mag[1:]) < 0)[0]]
    return np.array(wpc), np.array(wgc)


def test_every_crossing_of_a_lightly_damped_resonant_loop_is_kept():
    num, den = _resonant_loop()
    want_pc, want_gc = _dense_crossings(num, den)
    assert want_gc.size == 3 and want_pc.size >= 1  # the test can fail: several genuine crossings
    for loop in (ct.ss(ct.tf(num, den)), ct.tf(num, den)):
        wpc, gm, wgc, pm = crossings(loop)
        np.testing.assert_allclose(wgc, want_gc, rtol=1e-8)
        np.testing.assert_allclose(wpc, want_pc, rtol=1e-8)
    m = loop_margins(ct.ss(ct.tf(num, den)), ct.ss(ct.feedback(ct.tf(num, den), 1)))
    assert len(m.gain_crossover_hz) == 3 and len(m.phase_crossover_hz) == want_pc.size


def _exact_response(A, B, C, D, w) -> complex:
    """C (jw I - A)^-1 B + D in exact rational arithmetic (complex numbers as pairs)."""
    n = A.shape[0]
    zero = Fraction(0)
    M = [[(Fraction(-float(A[i, j])), Fraction(float(w)) if i == j else zero) for j in range(n)] for i in range(n)]
    rhs = [(Fraction(float(B[i, 0])), zero) for i in range(n)]

    def mul(a, b):
        return a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0]

    def div(a, b):
        d = b[0] * b[0] + b[1] * b[1]
        return (a[0] * b[0] + a[1] * b[1]) / d, (a[1] * b[0] - a[0] * b[1]) / d

    for k in range(n):
        piv = next(r for r in range(k, n) if M[r][k] != (zero, zero))
        M[k], M[piv], rhs[k], rhs[piv] = M[piv], M[k], rhs[piv], rhs[k]
        for r in range(k + 1, n):
            f = div(M[r][k], M[k][k])
            M[r] = [(M[r][c][0] - mul(f, M[k][c])[0], M[r][c][1] - mul(f, M[k][c])[1]) for c in range(n)]
            rhs[r] = (rhs[r][0] - mul(f, rhs[k])[0], rhs[r][1] - mul(f, rhs[k])[1])
    x = [None] * n
    for k in reversed(range(n)):
        acc = rhs[k]
        for c in range(k + 1, n):
            p = mul(M[k][c], x[c])
            acc = (acc[0] - p[0], acc[1] - p[1])
        x[k] = div(acc, M[k][k])
    re = Fraction(float(D[0, 0])) + sum(Fraction(float(C[0, i])) * x[i][0] for i in range(n))
    im = sum(Fraction(float(C[0, i])) * x[i][1] for i in range(n))
    return complex(float(re), float(im))


@pytest.mark.parametrize("loop, freqs", [
    (ct.ss(ct.tf(*_resonant_loop())), (0.1, 9.9, 10.0, 300.0)),
    # a type-2 loop evaluated deep in its integrators' asymptote: an ill-conditioned solve
    (ct.ss(ct.tf([1.0, 0.1], [1.0, 1.0, 0.0, 0.0])), (1e-9, 1e-6, 1e-3, 1.0)),
])
def test_rounding_bound_covers_the_exact_error(loop, freqs):
    A, B, C, D = (np.asarray(m, float) for m in (loop.A, loop.B, loop.C, loop.D))
    f = response_of(loop)
    for w in freqs:
        exact = _exact_response(A, B, C, D, w)
        err = abs(f(np.array([1j * w]))[0] - exact) / abs(exact)
        bound = float(rounding_bound(loop, [w])[0])
        assert err <= bound and bound < 1e-6, (w, err, bound)


def test_resolvable_range_is_the_crossing_tolerance_over_epsilon():
    assert RESOLVABLE_DB == pytest.approx(20 * math.log10(CROSSING_TOL / EPS))
    assert 190 < RESOLVABLE_DB < 196


def test_shipped_cam_scene_lists_no_crossing_in_the_rounding():
    """The cam follower's lead-lag loop: its phase touches -180 deg only on the integrators'
    asymptote at 9 nHz, where |L| = 6.6e17 (a "gain margin" of -356 dB that 1 + L, rounding
    to L, cannot see); it used to be listed. The real crossings are unchanged."""
    import servo_toolkit as st
    cam = st.load_scene(SCENES / "cam_follower.toml")
    r = st.design(cam, structure="lead_lag", robust=False, progress=False)
    m = r.margins
    assert all(abs(g) <= RESOLVABLE_DB for g in m.gain_margins_db)
    assert not any(f < 1e-3 for f in m.phase_crossover_hz)
    # the dropped point: L there is real and negative but beyond the resolvable range, exactly
    A, B, C, D = (np.asarray(x, float) for x in (r.loop.A, r.loop.B, r.loop.C, r.loop.D))
    w = 2 * math.pi * 8.909e-9
    exact = _exact_response(A, B, C, D, w)
    assert exact.real < 0 and 20 * math.log10(abs(exact)) > RESOLVABLE_DB
    # the gain crossing stays, with the phase margin the independent evaluation gives
    fc, = m.gain_crossover_hz
    lw = _exact_response(A, B, C, D, 2 * math.pi * fc)
    assert abs(abs(lw) - 1) < 1e-6
    assert m.phase_margin_deg == pytest.approx(math.degrees(np.angle(lw)) + 180, abs=1e-6)
