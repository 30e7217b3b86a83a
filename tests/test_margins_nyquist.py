"""Margins on the Nyquist criterion, checked by what each figure claims, over random loops:
a gain margin g at w puts a closed-loop pole of g L at +-jw, a phase margin pm makes
1 + e^{-j pm} L vanish at the gain crossing, a delay margin tau makes the exactly delayed loop
touch -1 there, and the stability verdict and the Nyquist count equal the closed-loop poles."""

from __future__ import annotations

import math
import warnings

import control as ct
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from servo_toolkit.loop.margins import loop_margins

warnings.filterwarnings("ignore", module="control")


@st.composite
def loops(draw):
    """A well-conditioned rational loop: 1-4 real or complex poles (stable or not), up to
    two zeros, optionally an integrator, and a gain over four decades."""
    poles = []
    for _ in range(draw(st.integers(1, 3))):
        if draw(st.booleans()):
            poles.append(draw(st.floats(-20, 5).filter(lambda x: abs(x) > 0.05)))
        else:
            re, im = draw(st.floats(-5, 1).filter(lambda x: abs(x) > 0.02)), draw(st.floats(0.2, 20))
            poles += [complex(re, im), complex(re, -im)]
    if draw(st.booleans()):
        poles.append(0.0)
    zeros = [draw(st.floats(-30, 10).filter(lambda x: abs(x) > 0.05)) for _ in range(draw(st.integers(0, 2)))]
    zeros = zeros[:max(0, len(poles) - 1)]
    k = 10 ** draw(st.floats(-2, 2))
    den = np.real(np.poly(poles))
    num = k * np.real(np.poly(zeros)) if zeros else np.array([k])
    return ct.tf(num, den)


def _cl_poles(L):
    num, den = np.squeeze(L.num[0][0]), np.squeeze(L.den[0][0])
    return np.roots(np.polyadd(den, num))


def _scale(L):
    return max(1.0, float(np.max(np.abs(np.concatenate([ct.poles(L), ct.zeros(L)])))))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(loops())
def test_every_figure_means_what_it_says(L):
    m = loop_margins(L, ct.feedback(L, 1))
    scale = _scale(L)
    cl = _cl_poles(L)
    # stability: the verdict and the Nyquist count both equal the closed-loop poles
    if np.min(np.abs(cl.real)) < 1e-6 * scale:
        return  # a pole on the axis: the verdict is a matter of rounding
    assert m.closed_loop_stable == bool(np.all(cl.real < 0))
    assert m.nyquist_rhp_closed_loop_poles == int(np.sum(cl.real > 0))
    for g_db, f in zip(m.gain_margins_db, m.phase_crossover_hz):
        if not math.isfinite(f):
            continue
        w = 2 * math.pi * f
        poles = _cl_poles(L * 10 ** (g_db / 20))
        assert np.min(np.abs(poles - 1j * w)) <= 1e-5 * scale * max(1.0, 10 ** (abs(g_db) / 20)), (g_db, f)
    for pm, f, tau in zip(m.phase_margins_deg, m.gain_crossover_hz, m.delay_margins_s):
        w = 2 * math.pi * f
        lw = complex(L(1j * w))
        assert abs(1 + np.exp(-1j * math.radians(pm)) * lw) <= 1e-6
        if m.closed_loop_stable and math.isfinite(tau) and w > 0:
            assert abs(1 + lw * np.exp(-1j * w * tau)) <= 1e-6  # the exact delay, frequency domain
    if m.closed_loop_stable:
        assert math.isfinite(m.sensitivity_peak_db)
    else:
        assert math.isnan(m.sensitivity_peak_db) and math.isnan(m.disk_margin)
        assert m.to_dict()["sensitivity_peak_db"] is None and any("not defined" in n for n in m.notes)


def test_open_loop_unstable_first_order():
    """L = 2/(s-1): stable closed loop (pole at -1); halving the gain puts the pole at 0."""
    L = ct.tf([2], [1, -1])
    m = loop_margins(L, ct.feedback(L, 1))
    assert m.closed_loop_stable and m.open_loop_rhp_poles == 1
    assert m.gain_margins_db == pytest.approx((20 * math.log10(0.5),))
    assert m.phase_crossover_hz == (0.0,)
    assert m.gain_margin_db == pytest.approx(-6.0206, abs=1e-4)
    assert m.lower_gain_margin_db == pytest.approx(-6.0206, abs=1e-4) and m.upper_gain_margin_db == math.inf


def test_unstable_closed_loop_has_no_ms_or_disk_margin():
    L = ct.tf([10], [1, 3, 3, 1])
    m = loop_margins(L, ct.feedback(L, 1))
    assert not m.closed_loop_stable and m.nyquist_rhp_closed_loop_poles == 2
    d = m.to_dict()
    assert d["sensitivity_peak_db"] is None and d["disk_margin"] is None


def test_integrator_asymptote_is_not_a_margin():
    """A type-2 loop's phase is -180 deg at w -> 0 because of its integrators: no margin."""
    L = ct.tf([4, 2], [1, 0, 0])
    m = loop_margins(L, ct.feedback(L, 1))
    assert m.integrators == 2 and m.gain_margins_db == () and m.closed_loop_stable
