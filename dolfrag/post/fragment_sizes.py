"""Fragment mass distributions fitted by maximum likelihood (docs/fragments.md).

The cumulative number of fragments heavier than m (kg; kg/m in 2D), for N0 fragments:

* Grady (exponential):  N(>m) = N0 exp(-m / mu). The masses are exponential with mean mu:
  the maximum-likelihood mu is the mean mass, standard error mu / sqrt(N0).
* Mott:                 N(>m) = N0 exp(-(m / mu)^(1/2)). Then sqrt(m) is exponential with
  mean sqrt(mu): the maximum-likelihood mu is the squared mean of sqrt(m), standard error
  2 mu / sqrt(N0) (delta method: d mu / mu = 2 d sqrt(mu) / sqrt(mu)).

N0 is the number of fragments fitted; the mass scale mu (kg) is the one parameter.
"""
from typing import NamedTuple

import numpy as np

MIN_FRAGMENTS = 2  # fewer pieces make no distribution


class Fit(NamedTuple):
    """mu: the mass scale (kg); standard_error (kg); log_likelihood of the sample (the larger
    fits better: both models have one parameter)."""
    mu: float
    standard_error: float
    log_likelihood: float


def grady(masses):
    """The Grady (exponential) Fit of ``masses`` (kg, > 0)."""
    m = np.asarray(masses, dtype=float)
    mu = m.mean()
    return Fit(mu, mu / np.sqrt(len(m)), -len(m) * np.log(mu) - m.sum() / mu)


def mott(masses):
    """The Mott Fit of ``masses`` (kg, > 0): density exp(-sqrt(m / mu)) / (2 sqrt(mu m))."""
    m = np.asarray(masses, dtype=float)
    root = np.sqrt(m)
    mu = root.mean() ** 2
    log_likelihood = -len(m) * np.log(2 * np.sqrt(mu)) - np.log(root).sum() - root.sum() / np.sqrt(mu)
    return Fit(mu, 2 * mu / np.sqrt(len(m)), log_likelihood)


def grady_count(m, n0, mu):
    """N(>m) of the Grady distribution."""
    return n0 * np.exp(-np.asarray(m) / mu)


def mott_count(m, n0, mu):
    """N(>m) of the Mott distribution."""
    return n0 * np.exp(-np.sqrt(np.asarray(m) / mu))


def block(masses, unit="kg"):
    """JSON-ready fits of ``masses`` (in ``unit``: kg, or kg/m in 2D): fragments (N0), the
    unit, and for each model its mu, standard_error (in ``unit``) and log_likelihood (None
    with fewer than MIN_FRAGMENTS), and the model of the larger likelihood as ``better``."""
    n = len(masses)
    if n < MIN_FRAGMENTS:
        return {"fragments": n, "unit": unit, "grady": None, "mott": None, "better": None}
    fits = {"grady": grady(masses), "mott": mott(masses)}
    return {"fragments": n, "unit": unit,
            **{name: {"mu": fit.mu, "standard_error": fit.standard_error, "log_likelihood": fit.log_likelihood}
               for name, fit in fits.items()},
            "better": max(fits, key=lambda name: fits[name].log_likelihood)}
