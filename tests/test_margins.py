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


# --- delay margin: every crossing of a stable loop, negative phase margins included ---------

#: L = k / (s (1 + s/a)^2) * wp^2 / (s^2 + 2 zeta wp s + wp^2): an integrator loop with a
#: lightly damped, non-collocated mode whose peak rises above 0 dB after the phase has passed
#: -180 deg (with |L| < 1 there), so the closed loop is stable with three gain crossings, two
#: of them at negative phase margins; the fastest one sets the delay margin.
_K, _A, _WP, _ZETA = 10.0, 80.0, 100.0, 0.01


def _resonant_loop():
    return (ct.tf([_K], [1, 0]) * ct.tf([1], [1 / _A, 1]) ** 2
            * ct.tf([_WP ** 2], [1, 2 * _ZETA * _WP, _WP ** 2]))


def _gain_crossings_closed_form():
    """Positive real roots of |den(jw)|^2 - |num(jw)|^2, a polynomial in w."""
    den = np.polymul(np.polymul([1, 0], np.polymul([1 / _A, 1], [1 / _A, 1])), [1, 2 * _ZETA * _WP, _WP ** 2])
    n = len(den) - 1
    # den(jw) = sum c_m (jw)^m: real and imaginary parts as polynomials in w (highest first)
    jw = np.array([1j ** (n - i) for i in range(n + 1)])
    re, im = np.real(den * jw), np.imag(den * jw)
    p = np.polyadd(np.polymul(re, re), np.polymul(im, im))
    p = np.polysub(p, [(_K * _WP ** 2) ** 2])
    r = np.roots(p)
    return np.sort(r[(np.abs(r.imag) < 1e-6 * np.abs(r)) & (r.real > 0)].real)


def test_delay_margin_of_a_stable_loop_with_negative_phase_margins():
    L = _resonant_loop()
    m = _margins(L)
    assert m.closed_loop_stable
    wc = _gain_crossings_closed_form()
    assert len(wc) == 3
    np.testing.assert_allclose(sorted(m.gain_crossover_hz), wc / (2 * np.pi), rtol=1e-8)
    # the smallest delay with L(jwc) exp(-j wc tau) = -1: wc tau = (arg L(jwc) + pi) mod 2 pi
    lw = np.array([complex(L(1j * w)) for w in wc])
    tau = np.remainder(np.angle(lw) + np.pi, 2 * np.pi) / wc
    pm = np.degrees(np.remainder(np.angle(lw), 2 * np.pi)) - 180
    assert np.sum(pm < 0) == 2
    order = np.argsort(m.gain_crossover_hz)
    np.testing.assert_allclose(np.array(m.phase_margins_deg)[order], pm, atol=1e-6)
    np.testing.assert_allclose(np.array(m.delay_margins_s)[order], tau, rtol=1e-8)
    assert m.delay_margin_s == pytest.approx(tau.min(), rel=1e-8)
    assert pm[np.argmin(tau)] < 0  # the binding crossing has a negative phase margin


def _max_pole_real_with_delay(L, tau, order=14):
    delay = ct.tf(*ct.pade(tau, order))
    return float(np.max(ct.poles(ct.feedback(L * delay, 1)).real))


def test_delay_margin_is_the_stability_limit_under_a_delay():
    # a Pade(14) delay (phase exact to ~1e-9 rad up to w tau = 4) below the margin keeps the
    # closed loop stable, above it destabilizes it, and at it the closed loop has poles on
    # the imaginary axis at the binding crossover
    L = _resonant_loop()
    m = _margins(L)
    tau = m.delay_margin_s
    assert _max_pole_real_with_delay(L, 0.97 * tau) < 0
    assert _max_pole_real_with_delay(L, 1.03 * tau) > 0
    wc = 2 * np.pi * m.gain_crossover_hz[int(np.argmin(m.delay_margins_s))]
    poles = ct.poles(ct.feedback(L * ct.tf(*ct.pade(tau, 14)), 1))
    assert np.min(np.abs(poles - 1j * wc)) < 1e-4 * wc


def test_every_crossing_delay_is_where_stability_changes():
    # each crossing's delay puts closed-loop poles on the imaginary axis: across the falling
    # crossing's (|L| decreasing) the loop destabilizes, across the rising crossing's
    # (|L| increasing, Re ds/dtau = -w dln|L|/dw / |...|^2 < 0) it recovers, and the falling
    # crossing destabilizes it again one period 2 pi / wc later
    L = _resonant_loop()
    m = _margins(L)
    order = np.argsort(m.gain_crossover_hz)
    wc = 2 * np.pi * np.array(m.gain_crossover_hz)[order]
    _, rising, falling = np.array(m.delay_margins_s)[order]
    assert falling < rising < falling + 2 * np.pi / wc[2]
    assert _max_pole_real_with_delay(L, 0.5 * (falling + rising)) > 0
    assert _max_pole_real_with_delay(L, 0.5 * (rising + falling + 2 * np.pi / wc[2]), 20) < 0
    assert _max_pole_real_with_delay(L, 1.03 * (falling + 2 * np.pi / wc[2]), 20) > 0


def test_unstable_closed_loop_has_no_margins():
    # L = 3 / (s (s + 1)^2): unstable for k > 2 (two closed-loop poles in the right half-plane,
    # Routh: s^3 + 2 s^2 + s + 3 has two sign changes in its first column 1, 2, -0.5, 3);
    # no margin of any kind, while the phase crossing is still where L is -3/2
    m = _margins(ct.tf([3], [1, 2, 1, 0]))
    assert not m.closed_loop_stable and m.unstable_closed_loop_poles == 2
    for x in (m.gain_margin_db, m.phase_margin_deg, m.delay_margin_s, m.lower_gain_margin_db,
              m.upper_gain_margin_db, m.disk_margin, m.sensitivity_peak_db, m.bandwidth_hz):
        assert math.isnan(x)
    assert all(math.isnan(d) for d in m.delay_margins_s)
    np.testing.assert_allclose(m.gain_margins_db, [20 * math.log10(2 / 3)], atol=1e-9)
    assert "2 closed-loop poles in the right half-plane" in m.unstable_reason
    d = m.to_dict()
    assert d["gain_margin_db"] is None and d["delay_margins_s"] == [None] and d["unstable_reason"]


def test_delay_margin_of_a_designed_loop_with_a_resonant_crossing():
    # the reference EMA's lead-lag loop without a resonance filter, its gain raised by 1.5 so
    # that the drivetrain resonance pokes through 0 dB: stable, with resonant crossings of
    # negative phase margin; a Pade delay confirms the headline delay margin
    import control as ct

    from servo_toolkit.loop import design
    from servo_toolkit.scene.loader import load_scene
    r = design(load_scene(), structure="lead_lag", resonance_filter="none", progress=False, over_stroke=False)
    loop = r.loop * 1.5
    m = loop_margins(loop, ct.feedback(loop, 1))
    assert m.closed_loop_stable and min(m.phase_margins_deg) < 0 and len(m.phase_margins_deg) >= 3
    assert m.delay_margin_s == min(m.delay_margins_s) > 0
    for pm, f, dm in zip(m.phase_margins_deg, m.gain_crossover_hz, m.delay_margins_s):
        assert dm == pytest.approx(math.radians(pm % 360) / (2 * math.pi * f), rel=1e-12)
    assert _max_pole_real_with_delay(loop, 0.95 * m.delay_margin_s, 10) < 0
    assert _max_pole_real_with_delay(loop, 1.05 * m.delay_margin_s, 10) > 0
