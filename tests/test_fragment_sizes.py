"""The Grady and Mott fits of fragment masses (post/fragment_sizes.py): each recovers its mass
scale mu from a sample drawn from it, within the standard error its sample size gives."""
import numpy as np
import pytest
from scipy import stats

from dolfrag.post import fragment_sizes

MU = 0.3     # kg
N = 4000     # fragments per sample
# 4 standard errors: a seeded sample lands outside with probability 6e-5; the estimators are
# unbiased (Grady) or biased by O(1/N) (Mott), far below that
K = 4.0


def grady_sample(n, mu, rng):
    """Masses with N(>m) = n exp(-m / mu)."""
    return rng.exponential(mu, n)


def mott_sample(n, mu, rng):
    """Masses with N(>m) = n exp(-(m / mu)^(1/2)): sqrt(m / mu) is exponential with mean 1."""
    return mu * rng.exponential(1.0, n) ** 2


@pytest.mark.parametrize("name, sample, relative_error", [("grady", grady_sample, 1.0), ("mott", mott_sample, 2.0)])
def test_the_fit_recovers_mu_within_its_standard_errors(name, sample, relative_error):
    masses = sample(N, MU, np.random.default_rng(7))
    fit = getattr(fragment_sizes, name)(masses)
    # standard error: mu / sqrt(N) (Grady), 2 mu / sqrt(N) (Mott): 0.016 and 0.032 of mu
    assert fit.standard_error == pytest.approx(relative_error * fit.mu / np.sqrt(N), rel=1e-12)
    assert abs(fit.mu - MU) < K * relative_error * MU / np.sqrt(N), (fit.mu, MU)
    block = fragment_sizes.block(masses)
    assert block["better"] == name and block["fragments"] == N and block[name]["mu"] == fit.mu


@pytest.mark.parametrize("name, sample", [("grady", grady_sample), ("mott", mott_sample)])
def test_the_standard_error_is_the_spread_of_the_fit_over_repeated_samples(name, sample):
    rng, n, repeats = np.random.default_rng(11), 100, 400
    fits = [getattr(fragment_sizes, name)(sample(n, MU, rng)) for _ in range(repeats)]
    spread = np.std([f.mu for f in fits], ddof=1)
    # the sample standard deviation of 400 values is within 3.5 % (one s.e.) of the true one;
    # 15 % leaves 4 of those and the delta method's O(1/n) for Mott
    assert spread == pytest.approx(np.mean([f.standard_error for f in fits]), rel=0.15)


def test_log_likelihoods_are_scipys_exponential_and_weibull_of_shape_one_half():
    masses = mott_sample(50, MU, np.random.default_rng(3))
    grady, mott = fragment_sizes.grady(masses), fragment_sizes.mott(masses)
    assert grady.log_likelihood == pytest.approx(stats.expon(scale=grady.mu).logpdf(masses).sum(), rel=1e-12)
    assert mott.log_likelihood == pytest.approx(stats.weibull_min(0.5, scale=mott.mu).logpdf(masses).sum(), rel=1e-12)
    # and they are maxima: a mu 1 % off is less likely
    for fit, model in ((grady, fragment_sizes.grady_count), (mott, fragment_sizes.mott_count)):
        assert model(fit.mu, 10, fit.mu) == pytest.approx(10 * np.exp(-1.0), rel=1e-15)  # N(> mu) = N0 / e
    for off in (0.99, 1.01):
        assert stats.weibull_min(0.5, scale=off * mott.mu).logpdf(masses).sum() < mott.log_likelihood
        assert stats.expon(scale=off * grady.mu).logpdf(masses).sum() < grady.log_likelihood


def test_one_fragment_makes_no_distribution():
    assert fragment_sizes.block([1.0], "kg/m") == {"fragments": 1, "unit": "kg/m", "grady": None, "mott": None,
                                                   "better": None}
