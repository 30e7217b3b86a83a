"""Tolerances at their edges: a single live input to the Sobol indices, degenerate and
implicitly truncated distributions, yields that no sample can show, the text's units and
intervals, and the reproducibility of the draws."""

from __future__ import annotations

import numpy as np
import pytest


def test_sobol_indices_of_a_single_input_keep_one_column_per_figure():
    from scipy.stats import uniform

    from servo_toolkit.core.sensitivity import sobol

    def f(x):  # three figures of one input: each is all of its own variance
        return np.vstack([x[0] ** 2, np.sin(3 * x[0]), x[0]])
    res = sobol(f, [uniform(0, 1)], 64, seed=0, resamples=20)
    for k in ("first", "total", "total_low", "total_high"):
        assert np.shape(res[k]) == (3, 1), k
    # one input carries all of the variance: S_1 = S_T = 1 (Saltelli's estimators, exact here)
    np.testing.assert_allclose(res["total"][:, 0], 1.0, atol=0.05)
