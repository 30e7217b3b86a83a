"""The separable fit's verification inputs: a box corner the samples never come near is
verified (and refined on) when the caller names it."""

import numpy as np

from servo_toolkit.core.separable import DEFAULT_RTOL, fit


def _exact(X):
    """y = x1 + x2 + 10 (x1 - 0.8)+ (x2 - 0.8)+: separable except where both keys exceed 0.8."""
    X = np.atleast_2d(X)
    bump = 10.0 * np.clip(X[:, 0] - 0.8, 0, None) * np.clip(X[:, 1] - 0.8, 0, None)
    return np.column_stack([X[:, 0] + X[:, 1] + bump])


#: samples over the unit square, none with both keys above 0.8
SAMPLES = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 0.5], [0.5, 1.0], [0.3, 0.7]])
X0 = np.array([0.5, 0.5])
CORNER = np.array([[1.0, 1.0]])


def test_a_named_corner_is_verified_where_the_samples_miss_it():
    plain = fit(_exact, X0, SAMPLES)
    # exact on every sample, and so accepted ...
    np.testing.assert_allclose(plain(SAMPLES), _exact(SAMPLES), rtol=1e-12, atol=1e-12)
    assert plain.error <= DEFAULT_RTOL
    # ... though 0.4 off (of 2.4) at the box's corner
    assert abs(plain(CORNER) - _exact(CORNER))[0, 0] > 0.3
    checked = fit(_exact, X0, SAMPLES, checks=CORNER)
    # the corner's error is reported (relative to the largest output, 2.4); no pair term
    # c (x1 - 0.5)(x2 - 0.5) fits a bump at one corner, so the fit does not verify
    gap = float(np.max(np.abs(checked(CORNER) - _exact(CORNER)) / 2.4))
    assert checked.error >= gap * (1 - 1e-12) and gap > 10 * DEFAULT_RTOL
    assert checked.evaluations > plain.evaluations  # the corner's evaluation and the refinement


def test_points_per_key_set_each_key_s_grid():
    """A smooth key needs fewer exact evaluations than a steep one: one count per key."""
    def exact(X):
        X = np.atleast_2d(X)
        return np.column_stack([np.exp(3.0 * X[:, 0]) + 2.0 * X[:, 1]])
    one = fit(exact, X0, SAMPLES, points=((9, 3),))
    assert [g.size for g in one.grids] == [9, 3]
    assert one.evaluations == 1 + 4 + 9 + 3  # nominal, farthest and random checks, the grids
    np.testing.assert_allclose(one(SAMPLES), exact(SAMPLES), rtol=1e-3)
