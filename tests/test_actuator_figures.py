"""The signal figures of the nonlinear rows (``studies.actuator.figures``) against closed forms."""

import math

import numpy as np
import pytest

from servo_toolkit.studies.actuator.figures import limit_cycle, ripple, step_figures, time_at_limit


def _second_order(t, zeta, wn):
    wd = wn * math.sqrt(1 - zeta ** 2)
    return 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2) * np.sin(wd * t))


@pytest.mark.parametrize("zeta", [0.2, 0.45, 0.7])
def test_the_overshoot_of_a_second_order_step_is_the_textbook_one(zeta):
    """Overshoot exp(-zeta pi / sqrt(1 - zeta^2)); the settling time within the envelope's bound
    -ln(band sqrt(1 - zeta^2)) / (zeta wn) and after the last peak outside the band."""
    wn = 2 * math.pi * 10
    t = np.linspace(0.0, 2.0, 400001)
    y = 3.0 * _second_order(t, zeta, wn)   # a step of 3
    over, settle = step_figures(t, y, 3.0, 0.06)  # band 2 %
    assert over == pytest.approx(math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2)), rel=1e-5)
    bound = -math.log(0.02 * math.sqrt(1 - zeta ** 2)) / (zeta * wn)
    assert settle <= bound + 1e-5
    assert abs(y[t >= settle][0] / 3.0 - 1.0) <= 0.02 + 1e-6
    assert np.max(np.abs(y[t < settle - 1e-3] / 3.0 - 1.0)) > 0.02


def test_a_first_order_step_settles_at_tau_ln50_and_one_that_ends_outside_never_settles():
    tau = 0.05
    t = np.linspace(0.0, 1.0, 100001)
    over, settle = step_figures(t, -(1 - np.exp(-t / tau)), -1.0, 0.02)   # a negative step
    assert over == 0.0 and settle == pytest.approx(tau * math.log(50), abs=2e-5)
    _, never = step_figures(t, 0.9 * (1 - np.exp(-t / tau)), 1.0, 0.02)
    assert never == math.inf


def test_a_limit_cycle_is_read_with_its_amplitude_and_frequency_and_a_creep_is_none():
    t = np.linspace(0.0, 0.5, 50001)
    cyc = limit_cycle(t, 0.3 + 2e-3 * np.sin(2 * math.pi * 37.0 * t + 0.4), 1e-5)
    assert cyc.amplitude == pytest.approx(2e-3, rel=1e-4) and cyc.frequency == pytest.approx(37.0, rel=0.03)
    assert limit_cycle(t, 0.3 + 1e-3 * np.exp(-t / 0.1), 1e-6) is None      # a creep to rest: no cycle
    assert limit_cycle(t, 0.3 + 1e-7 * np.sin(2 * math.pi * 37.0 * t), 1e-6) is None  # below the resolution


def test_the_ripple_is_the_rms_above_the_cutoff_whatever_the_motion_below_it():
    """A 5 Hz motion current with its odd harmonics to the ninth, a drift, and a 0.3 A chatter
    at 212 Hz: the ripple above 50 Hz is the chatter's 0.3 / sqrt(2) A, over whole periods
    and over a window that is not."""
    t = np.linspace(0.0, 0.6, 6001)
    motion = sum(2.0 / k * np.sin(2 * math.pi * 5 * k * t) for k in (1, 3, 5, 7, 9)) + 4.0 + 3.0 * t
    chatter = 0.3 * np.sin(2 * math.pi * 212.0 * t + 1.0)
    assert ripple(t, motion + chatter, 50.0) == pytest.approx(0.3 / math.sqrt(2), rel=0.02)
    part = t <= 0.537
    assert ripple(t[part], motion[part] + chatter[part], 50.0) == pytest.approx(0.3 / math.sqrt(2), rel=0.05)
    assert ripple(t, motion, 50.0) < 0.01


def test_the_time_at_a_limit_counts_a_current_pinned_at_99_percent():
    """|A sin| within 1 % of a limit L for T (1 - 2 asin(0.99 L / A) / pi); a current at
    99.3 % of its limit for 100 ms is at the limit (a 0.1 % band read 0 ms)."""
    t = np.linspace(0.0, 1.0, 200001)
    a, lim = 12.0, 10.0
    expected = 1.0 - 2.0 * math.asin(0.99 * lim / a) / math.pi
    assert time_at_limit(t, a * np.sin(2 * math.pi * 7 * t), lim) == pytest.approx(expected, rel=1e-3)
    pinned = np.where((t > 0.2) & (t < 0.3), 9.93, 3.0)
    assert time_at_limit(t, pinned, lim) == pytest.approx(0.1, abs=1e-4)
    assert time_at_limit(t, pinned, math.inf) == 0.0


def test_a_step_still_moving_reads_no_cycle_and_says_it_moves():
    """A response creeping through the rest window has no limit cycle (figure 0), and the
    row's words say the output still moves there instead of "none"."""
    from types import SimpleNamespace

    from servo_toolkit.core.output_units import OutputUnit
    from servo_toolkit.studies.actuator.result import _step_figures
    from servo_toolkit.studies.actuator.runs import STEP_AT
    t = np.linspace(0.0, 0.6, 60001)
    after = np.clip(t - STEP_AT, 0.0, None)
    step = math.radians(1.0)
    for tau, moving in ((0.02, False), (0.5, True)):
        y = step * (1 - np.exp(-after / tau))
        run = SimpleNamespace(times=t, output_angle=y, motor_current=np.zeros_like(t),
                              trace=lambda name, y=y: y)
        plan = SimpleNamespace(step=step, rest_band=0.02 * step, settling_time=0.2, frequency=8.0)
        figures, details = {}, {}
        _step_figures(plan, run, OutputUnit("rad"), figures, details)
        assert figures["limit_cycle"] == 0.0
        words = details["limit_cycle"]
        assert words.startswith("no cycle, but the output still moves") == moving, words
        assert words.startswith("none") != moving, words
