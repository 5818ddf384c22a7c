"""U[lower, upper], G[mean, std] and constants: statistics, positivity, reproducibility."""
import numpy as np
import pytest
from scipy import stats

from scratch_iridescence.mitsuba_bridge.scratch import Constant, Gaussian, Uniform, parse_distribution

N = 200_000


def test_uniform_matches_its_distribution():
    values = Uniform(2e-6, 6e-6).sample(np.random.default_rng(1), N)
    assert values.min() >= 2e-6 and values.max() <= 6e-6
    assert stats.kstest(values, stats.uniform(2e-6, 4e-6).cdf).pvalue > 1e-3


def test_uniform_from_zero_never_draws_zero():
    values = Uniform(0.0, 6e-6).sample(np.random.default_rng(2), N)
    assert np.all(values > 0)
    assert stats.kstest(values, stats.uniform(0, 6e-6).cdf).pvalue > 1e-3


def test_gaussian_matches_its_distribution():
    values = Gaussian(4e-6, 1.3e-6).sample(np.random.default_rng(3), N)
    # Truncation at 0 is 3 sigma away: compare against the truncated normal.
    truncated = stats.truncnorm((0 - 4e-6) / 1.3e-6, np.inf, loc=4e-6, scale=1.3e-6)
    assert stats.kstest(values, truncated.cdf).pvalue > 1e-3
    assert abs(values.mean() - truncated.mean()) < 5 * truncated.std() / np.sqrt(N)


def test_gaussian_redraws_nonpositive_values():
    dist = Gaussian(250e-9, 200e-9)  # about 11 % of raw draws are <= 0
    values = dist.sample(np.random.default_rng(4), N)
    assert np.all(values > 0)
    truncated = stats.truncnorm(-250 / 200, np.inf, loc=250e-9, scale=200e-9)
    assert stats.kstest(values, truncated.cdf).pvalue > 1e-3


@pytest.mark.parametrize("dist", [Uniform(0, 6e-6), Gaussian(250e-9, 80e-9), Constant(1e-6)])
def test_sampling_is_reproducible(dist):
    a = dist.sample(np.random.default_rng(42), 1000)
    b = dist.sample(np.random.default_rng(42), 1000)
    np.testing.assert_array_equal(a, b)


def test_constant_and_degenerate_distributions():
    np.testing.assert_array_equal(Constant(120e-9).sample(np.random.default_rng(0), 3), [120e-9] * 3)
    np.testing.assert_array_equal(Uniform(1e-6, 1e-6).sample(np.random.default_rng(0), 2), [1e-6] * 2)
    np.testing.assert_array_equal(Gaussian(1e-6, 0).sample(np.random.default_rng(0), 2), [1e-6] * 2)


@pytest.mark.parametrize("make", [
    lambda: Uniform(5, 1), lambda: Uniform(-2, 0), lambda: Uniform(-1e9, 1e-9),
    lambda: Gaussian(-1, 0.1), lambda: Gaussian(1, -1), lambda: Gaussian(0, 0),
    lambda: Constant(0), lambda: Constant(float("nan")), lambda: Uniform(0, float("inf")),
])
def test_impossible_distributions_are_refused(make):
    with pytest.raises(ValueError):
        make()


def test_parse_the_papers_notation():
    assert parse_distribution("G[250, 80]", "nm") == Gaussian(250e-9, 80e-9)
    assert parse_distribution("U[0, 6]", "um") == Uniform(0.0, 6e-6)
    assert parse_distribution("120", "nm") == Constant(120e-9)
    with pytest.raises(ValueError, match="cannot read"):
        parse_distribution("Q[1, 2]")
