"""The profile of the cost (profile likelihood) against cases whose answer is known in closed
form: a model linear in its parameters (the profile is the Wald parabola), two parameters
entering only as their product (a flat profile), and a cost with a lower valley elsewhere."""

import math

import numpy as np
import pytest
from scipy import optimize, stats

from servo_toolkit.identify.fit import _intervals
from servo_toolkit.identify.profile import ParameterProfile, noise_variance, profile, threshold


@pytest.fixture(scope="module")
def linear():
    """y = a + b x + c x^2 + Gaussian noise: the least-squares estimate and its exact t interval."""
    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 1.0, 30)
    design = np.column_stack([np.ones_like(x), x, x ** 2])
    y = design @ [1.0, 2.0, -1.0] + rng.normal(0.0, 0.1, x.size)

    def residuals(z):
        return design @ z - y
    beta, rss, *_ = np.linalg.lstsq(design, y, rcond=None)
    dof = x.size - 3
    # the textbook interval: beta_j -+ t_{0.975, dof} s sqrt((X^T X)^-1_jj)
    half = stats.t.ppf(0.975, dof) * math.sqrt(rss[0] / dof) * np.sqrt(np.diag(np.linalg.inv(design.T @ design)))
    return residuals, beta, dof, half


def test_the_profile_of_a_linear_model_is_its_exact_interval(linear):
    residuals, beta, dof, half = linear
    s2 = noise_variance(residuals(beta), dof)
    for j in range(3):
        p = profile(residuals, beta, [-10.0] * 3, [10.0] * 3, j, s2, threshold(dof))
        assert p.identified and p.lower is None
        assert p.interval[0] == pytest.approx(beta[j] - half[j], abs=1e-3 * half[j])
        assert p.interval[1] == pytest.approx(beta[j] + half[j], abs=1e-3 * half[j])
        # and along the grid the rise is the parabola ((b - beta) / half)^2 t^2
        assert np.allclose(p.rise, ((p.z - beta[j]) / half[j]) ** 2 * threshold(dof), rtol=1e-6, atol=1e-8)


def test_the_threshold_is_the_f_quantile():
    assert threshold(10 ** 6) == pytest.approx(stats.chi2.ppf(0.95, 1), rel=1e-5)  # 3.84
    assert threshold(20) == pytest.approx(stats.f.ppf(0.95, 1, 20), rel=1e-9)


def test_two_parameters_entering_as_their_product_have_a_flat_profile():
    """y = exp(z0 + z1) exp(-x): only z0 + z1 shows. Each profile stays at the optimum's cost
    while the other can compensate (within its box), and is unbounded toward the side where it
    always can; the partner is named."""
    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 2.0, 25)
    y = 6.0 * np.exp(-x) + rng.normal(0.0, 0.05, x.size)

    def residuals(z):
        return np.exp(z[0] + z[1]) * np.exp(-x) - y
    lower, upper = np.array([-3.0, -5.0]), np.array([3.0, 5.0])
    sol = optimize.least_squares(residuals, [0.5, 0.5], bounds=(lower, upper))
    total = sol.x.sum()
    half, _, singular = _intervals(sol.jac, sol.fun, x.size - 2)
    assert singular.all() or not np.isfinite(half).all() or half.max() > 1.0  # the Jacobian knows it too
    s2 = noise_variance(sol.fun, x.size - 2)
    p = profile(residuals, sol.x, lower, upper, 0, s2, threshold(x.size - 2))
    # z1 = total - z0 stays within [-5, 5] for every z0 in [-3, 3]: flat over the whole box
    assert p.unbounded == (True, True) and p.partner == 1
    assert p.interval == (-3.0, 3.0)
    assert np.abs(p.rise).max() < 1e-6
    assert np.allclose(p.path[:, 0] + p.path[:, 1], total, atol=1e-6)
    q = profile(residuals, sol.x, lower, upper, 1, s2, threshold(x.size - 2))
    # z0 = total - z1 leaves [-3, 3] beyond z1 = total -+ 3: the cost rises there
    assert q.unbounded == (False, False) and q.partner is None
    flat = (q.z > total - 3.0 + 1e-6) & (q.z < total + 3.0 - 1e-6)
    assert flat.sum() >= 4 and np.abs(q.rise[flat]).max() < 1e-6
    assert total - 3.0 - 0.5 < q.interval[0] < total - 3.0 and total + 3.0 < q.interval[1] < total + 3.5


def test_a_lower_valley_on_the_profile_is_reported():
    """A cost with its lowest valley at z0 = 2 (the other parameter following z1 = z0), and a
    shallower one at z0 = 0 where the profile starts: the profile finds the lower one (a valley
    about as wide as the grid's step at its distance; a narrower one can fall between points)."""
    def residuals(z):
        dip = 1.0 - 0.9 * np.exp(-(z[0] - 2.0) ** 2 / 1.0)
        return np.array([dip * (1.0 + z[0] ** 2) ** 0.5, 10.0 * (z[1] - z[0]), 0.1])
    start = np.array([0.0, 0.0])
    p = profile(residuals, start, [-4.0, -4.0], [4.0, 4.0], 0, 1.0, threshold(20))
    assert p.lower is not None and p.lower[0] == pytest.approx(2.0, abs=0.5)
    assert p.lower[1] == pytest.approx(p.lower[0], abs=1e-3)  # the other parameter followed
    rss = [float(residuals(z) @ residuals(z)) for z in (p.lower, start)]
    assert p.rise.min() == pytest.approx(rss[0] - rss[1], rel=1e-9) and rss[0] < rss[1] - 0.3


def test_a_profile_reads_out_and_plots(linear):
    import matplotlib
    matplotlib.use("Agg")
    residuals, beta, dof, _ = linear
    p = profile(residuals, beta, [-10.0] * 3, [10.0] * 3, 1, noise_variance(residuals(beta), dof), threshold(dof))
    q = ParameterProfile(key="load.inertia", unit="kg*m^2", value=float(np.exp(beta[1])),
                         values=np.exp(p.z), rise=p.rise, threshold=p.threshold,
                         interval=tuple(np.exp(p.interval)), unbounded=p.unbounded, partner=None)
    d = q.to_dict()
    assert d["key"] == "load.inertia" and len(d["values"]) == len(d["rise"]) and d["unbounded"] == [False, False]
    assert "identified" in repr(q) and "kg*m^2" in repr(q)
    ax = q.plot()
    assert ax.get_xlabel() == "load.inertia [kg*m^2]" and "[-]" in ax.get_ylabel()
    assert any(abs(line.get_ydata()[0] - p.threshold) < 1e-12 for line in ax.get_lines()[1:2])
