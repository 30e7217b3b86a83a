"""Margins of textbook loops against closed forms."""

import math

import control as ct
import numpy as np
import pytest

from servo_toolkit.loop.margins import frequency_grid, loop_margins
from servo_toolkit.loop.metrics import grid_figures


def _margins(L):
    return loop_margins(ct.ss(L), ct.ss(ct.feedback(L, 1)))


@pytest.mark.parametrize("k", [0.5, 1.0, 1.5])
def test_third_order_loop_gain_margin(k):
    # L = k / (s (s + 1)^2): phase -180 deg at w = 1 where |L| = k / 2
    m = _margins(ct.tf([k], [1, 2, 1, 0]))
    np.testing.assert_allclose(m.gain_margin_db, 20 * math.log10(2 / k), atol=1e-6)
    np.testing.assert_allclose(m.phase_crossover_hz[0], 1 / (2 * math.pi), rtol=1e-6)
    assert m.closed_loop_stable == (k < 2)


def test_second_order_loop_phase_and_delay_margin():
    # L = 1 / (s (s + 1)): |L| = 1 at w^2 = (sqrt(5) - 1) / 2, PM = 90 deg - atan(w)
    w = math.sqrt((math.sqrt(5) - 1) / 2)
    pm = 90 - math.degrees(math.atan(w))
    m = _margins(ct.tf([1], [1, 1, 0]))
    np.testing.assert_allclose(m.phase_margin_deg, pm, rtol=1e-6)
    np.testing.assert_allclose(m.delay_margin_s, math.radians(pm) / w, rtol=1e-6)
    assert m.gain_margins_db == ()  # no phase crossing
    # |S| peak of 1 / (1 + L) = s (s + 1) / (s^2 + s + 1): max over w of that magnitude
    ww = np.logspace(-3, 3, 200001)
    s = 1j * ww
    np.testing.assert_allclose(m.sensitivity_peak_db, 20 * np.log10(np.max(np.abs(s * (s + 1) / (s * s + s + 1)))),
                               atol=1e-3)


def test_integrator_bandwidth_and_phase():
    # L = a / s: T = a / (s + a), |T| = -3 dB (python-control's drop) at a sqrt(10^0.3 - 1),
    # phase at f = -atan(2 pi f / a), Ms = 0 dB, disk margin 2
    a = 2 * math.pi * 8.0
    m = loop_margins(ct.ss(ct.tf([a], [1, 0])), ct.ss(ct.tf([a], [1, a])), phase_hz=8.0)
    np.testing.assert_allclose(m.bandwidth_hz, 8.0 * math.sqrt(10**0.3 - 1), rtol=1e-6)
    np.testing.assert_allclose(m.phase_at_freq_deg, -45.0, atol=1e-6)
    np.testing.assert_allclose(m.phase_margin_deg, 90.0, atol=1e-6)
    np.testing.assert_allclose(m.sensitivity_peak_db, 0.0, atol=1e-3)
    np.testing.assert_allclose(m.disk_margin, 2.0, rtol=1e-3)


def test_every_crossing_is_reported():
    # a lightly damped mode above crossover gives several phase crossings
    L = ct.tf([20], [1, 1, 0]) * ct.tf([400], [1, 2, 400]) * ct.tf([1], [0.01, 1])
    m = _margins(L)
    assert len(m.gain_margins_db) + len(m.phase_margins_deg) >= 2
    gm, pm, _, wpc, wgc, _ = ct.stability_margins(L, returnall=True)
    np.testing.assert_allclose(sorted(m.gain_margins_db), sorted(20 * np.log10(gm[wpc > 1e-3])), rtol=1e-9)


def test_grid_figures_agree_with_python_control():
    L = ct.tf([30], [1, 3, 0]) * ct.tf([1, 2], [1, 20])
    w = frequency_grid(points=4000, extra=[8.0])
    r = np.asarray(ct.frequency_response(L, w).complex).reshape(-1)
    f = grid_figures(w, r[None, :], phase_freq=8.0)
    m = _margins(L)
    np.testing.assert_allclose(f["phase_margin_deg"][0], m.phase_margin_deg, atol=0.05)
    np.testing.assert_allclose(f["bandwidth_hz"][0], m.bandwidth_hz, rtol=2e-3)
    np.testing.assert_allclose(f["sensitivity_peak_db"][0], m.sensitivity_peak_db, atol=0.01)
    np.testing.assert_allclose(f["phase_at_freq_deg"][0], m.phase_at_freq_deg, atol=0.05)
