"""The standardized regression's shares of a figure's variance are population quantities, and
their intervals cover them at their stated rate from one sample to another (checked by
simulation against models whose population shares are known in closed form); a
tolerance's population variance against its closed forms."""

from __future__ import annotations

import numpy as np
import pytest

#: independent samples per simulated coverage check, each of the study's size below
SAMPLES = 200
VARIANTS = 256


def _linear(u, rng):
    """y = sum b_k x_k + noise, x_k ~ U(0, 1): population shares b_k^2 V_k / Var(y)."""
    b, sigma = np.array([-0.95, -0.81, 0.3]), 0.02
    y = u @ b + sigma * rng.standard_normal(len(u))
    return y, b ** 2 / 12 / (b @ b / 12 + sigma ** 2)


def _curved(u, rng):
    """y = x_0^2 + x_1 + 0.3 x_2 + noise, x_k ~ U(0, 1): the best linear fit of x_0^2 has
    slope Cov(x, x^2) / Var(x) = (1/12) / (1/12) = 1, so the linear part of x_0 carries
    1/12 of the variance; Var(x_0^2) = 1/5 - 1/9 = 4/45."""
    sigma = 0.02
    y = u[:, 0] ** 2 + u[:, 1] + 0.3 * u[:, 2] + sigma * rng.standard_normal(len(u))
    return y, np.array([1 / 12, 1 / 12, 0.09 / 12]) / (4 / 45 + 1 / 12 + 0.09 / 12 + sigma ** 2)


@pytest.mark.parametrize("method, model", [("lhs", _linear), ("random", _curved)])
def test_share_intervals_cover_the_population_share_at_their_stated_rate(method, model):
    """Each of SAMPLES independent samples of VARIANTS variants (the study's own draws) gives
    every share a 95 % interval. If the intervals are honest, the count that holds the
    population share is Binomial(SAMPLES, 0.95) per tolerance: 190 expected, sd 3.1. The
    accepted band is that binomial's central 99.9 % (179..198 of 200), so the three checks
    of one case together fail an honest estimator by chance less than 0.3 % of the time;
    intervals that hold only one sample's fit (they ignore the columns' chance correlation)
    cover a share of ~0.65 at 256 variants about a fifth of the time."""
    from scipy.stats import binom

    from servo_toolkit.core.sensitivity import rank
    from servo_toolkit.loop.sampling import unit_sample
    rng = np.random.default_rng(11)
    held = np.zeros(3, int)
    for i in range(SAMPLES):
        u = unit_sample(3, VARIANTS, method, seed=100 + i)
        y, truth = model(u, rng)
        s = rank("f", "f", "", ("a", "b", "c"), u, y, variances=np.full(3, 1 / 12), seed=i)
        assert s.method == "src" and np.sum(s.share) <= 1.0  # a share of the population variance
        held += (s.low <= truth) & (truth <= s.high)
    low, high = binom.ppf(0.0005, SAMPLES, 0.95), binom.isf(0.0005, SAMPLES, 0.95)
    assert np.all((low <= held) & (held <= high)), (held, (low, high))


def test_shares_of_one_sample_do_not_take_the_columns_chance_correlation_for_variance():
    """Two columns drawn with a correlation below -0.3 (as chance might): the sample's var(y) is far
    below the population's, and SRC^2 on the sample's sd(y) would sum above 100 %; the
    population shares stay at b_k^2 V_k / Var(y) (1/2 each, both slopes 1)."""
    from servo_toolkit.core.sensitivity import rank
    rng = np.random.default_rng(5)
    u = rng.random((VARIANTS, 2))
    u[:, 1] = np.argsort(np.argsort(-0.5 * u[:, 0] + rng.random(VARIANTS))) / VARIANTS + 0.5 / VARIANTS
    assert np.corrcoef(u.T)[0, 1] < -0.3
    y = u[:, 0] + u[:, 1] + 0.01 * rng.standard_normal(VARIANTS)
    s = rank("f", "f", "", ("a", "b"), u, y, variances=np.full(2, 1 / 12))
    truth = (1 / 12) / (2 / 12 + 1e-4)
    assert np.all((s.low <= truth) & (truth <= s.high)), (s.low, s.high)
    assert np.sum(s.share) <= 1.0 and s.r2 > 0.99


@pytest.mark.parametrize("kind, expected", [
    ("uniform", (0.7 - 0.5) ** 2 / 12),
    ("log_uniform", np.log(100.0) ** 2 / 12),
    ("integer", (5 ** 2 - 1) / 12),  # 12..16, five equally likely whole numbers
    ("normal", None),
])
def test_a_tolerance_s_population_variance_is_its_distribution_s(kind, expected):
    from scipy.stats import truncnorm

    from servo_toolkit.scene.distributions import Tolerance
    t = {"uniform": Tolerance("motor.resistance", "ohm", 0.6, "uniform", 0.5, 0.7),
         "log_uniform": Tolerance("load.inertia", "kg", 1.0, "log_uniform", 0.1, 10.0),
         "integer": Tolerance("sensors.output_encoder_bits", "", 14, "uniform", 12, 16, integer=True),
         "normal": Tolerance("motor.torque_constant", "N*m/A", 0.25, "normal", 0.2375, 0.2625, 0.25, 0.005)}[kind]
    if expected is None:  # truncated at +-2.5 sigma: below sigma^2
        expected = truncnorm.var(-2.5, 2.5, loc=0.25, scale=0.005)
        assert expected < 0.005 ** 2
    # midpoints of 2^16 equal-probability strata: a smooth distribution to 1e-6, an integer
    # key's steps to one stratum in 2^16 per step
    rel = 5 * 2.0 ** -16 if kind == "integer" else 1e-6
    assert t.variance(log=kind == "log_uniform") == pytest.approx(expected, rel=rel)
