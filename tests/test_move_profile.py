"""Jerk-limited moves: continuity, bounded jerk, the distance reached and the duration against
the textbook closed forms of each case; the kernel's profile is the host's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.loop.profile import MoveProfile

#: (distance, v_max, a_max, j_max, the duration's closed form, which limits are reached)
CASES = [
    # both limits reached: T = D / v + v / a + a / j
    (1.0, 2.0, 10.0, 100.0, lambda d, v, a, j: d / v + v / a + a / j, "va"),
    # the speed limit reached before the acceleration one (v j < a^2): T = D / v + 2 sqrt(v / j)
    (1.0, 0.5, 10.0, 100.0, lambda d, v, a, j: d / v + 2 * math.sqrt(v / j), "v"),
    # too short for v_max, a_max reached: T = a / j + sqrt((a / j)^2 + 4 D / a)
    (0.2, 5.0, 10.0, 100.0, lambda d, v, a, j: a / j + math.sqrt((a / j) ** 2 + 4 * d / a), "a"),
    # too short for either: T = 4 (D / (2 j))^(1/3)
    (0.01, 5.0, 10.0, 100.0, lambda d, v, a, j: 4 * (d / (2 * j)) ** (1 / 3), ""),
    # a negative move, both limits reached
    (-1.0, 2.0, 10.0, 100.0, lambda d, v, a, j: -d / v + v / a + a / j, "va"),
]


@pytest.mark.parametrize("d, v, a, j, duration, reached", CASES)
def test_profile_continuous_bounded_and_reaches_the_distance(d, v, a, j, duration, reached):
    m = MoveProfile(d, v, a, j)
    assert m.duration == pytest.approx(duration(d, v, a, j), rel=1e-12)
    assert m.peak_speed <= v * (1 + 1e-12) and m.peak_acceleration <= a * (1 + 1e-12)
    assert ("v" in reached) == (m.peak_speed == pytest.approx(v, rel=1e-12))
    assert ("a" in reached) == (m.peak_acceleration == pytest.approx(a, rel=1e-12))
    n = 200001
    t = np.linspace(-0.1 * m.duration, 1.1 * m.duration, n)
    h = t[1] - t[0]
    r, rd, rdd = m.rates(t)
    # the end: the distance, at rest; the start: at rest
    assert r[-1] == pytest.approx(d, rel=1e-12) and rd[-1] == 0.0 and rdd[-1] == 0.0
    assert r[0] == 0.0 and rd[0] == 0.0 and rdd[0] == 0.0
    # continuity with bounded jerk: r'' moves by at most j h per step, r' by a h, r by v h
    assert np.max(np.abs(np.diff(rdd))) <= j * h * (1 + 1e-9)
    assert np.max(np.abs(np.diff(rd))) <= a * h * (1 + 1e-9)
    assert np.max(np.abs(np.diff(r))) <= v * h * (1 + 1e-9)
    # the analytic rates are the derivatives (central differences, O(h^2))
    np.testing.assert_allclose(np.gradient(r, h)[1:-1], rd[1:-1], atol=1e-3 * v)
    np.testing.assert_allclose(np.gradient(rd, h)[1:-1], rdd[1:-1], atol=2 * j * h)
    # the jerk takes the limit (the profile is time-optimal in its jerk phases), not less
    assert np.max(np.abs(np.diff(rdd))) >= j * h * (1 - 1e-6)


def test_profile_refuses_bad_limits():
    for args, key in (((0.0, 1, 1, 1), "move.distance"), ((1.0, -1, 1, 1), "move.v_max"),
                      ((1.0, 1, math.inf, 1), "move.a_max"), ((1.0, 1, 1, math.nan), "move.j_max")):
        with pytest.raises(SceneError) as err:
            MoveProfile(*args)
        assert err.value.key == key


def test_kernel_move_is_the_profile():
    """The kernel's move (REF_MOVE, its block in P's tail) at every time equals the host's."""
    from servo_toolkit.sim import layout as lo
    from servo_toolkit._physics._kernels import move_rates
    m = MoveProfile(-0.3, 2.0, 10.0, 100.0)
    P = np.zeros(lo.NP_HEADER + 4)
    P[lo.REF_KIND], P[lo.REF_OFF], P[lo.REF_T0] = lo.REF_MOVE, 0.25, 0.05
    P[lo.REF_F] = lo.NP_HEADER
    P[lo.NP_HEADER:] = m.block()
    t = np.linspace(0.0, m.duration + 0.1, 997)
    got = np.array([move_rates(x, P) for x in t])
    r, rd, rdd = m.rates(t - 0.05)
    np.testing.assert_allclose(got, np.column_stack([r + 0.25, rd, rdd]), rtol=0, atol=1e-13)
