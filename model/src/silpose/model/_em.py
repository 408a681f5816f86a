"""EM of the MPPCA as a map/reduce over row blocks ("shards"): the ONE implementation of its
E-step and M-step, used by the in-memory fit (all rows = one shard) and by the streaming and Ray
fits (Parquet shards, one at a time or in parallel).

Every quantity EM needs is a sum over rows, so each shard returns its sums and the driver adds
them up (Tipping & Bishop 1999, Appendix C; see ``_ppca.m_step_sums``):

    n                  rows in the shard
    loglik             sum_n log p(x_n | theta)             (the E-step's normaliser, nats)
    r (M,)             sum_n R_ni                            (responsibility-weighted counts)
    G (d, Mq + M)      sum_n R_ni x_n (x_n^T W_i) and sum_n R_ni x_n   (the S_i W_i products and sums)
    sq (M,)            sum_n R_ni ||x_n||^2                  (for the traces tr S_i)

A shard's memory is O(n_s (d + M q)) and the sums' O(d M q), whatever the dataset's size; no
d x d matrix is formed. Before EM one pass collects the data moments (row count, mean, sum of
squared deviations; combined across shards with Chan, Golub & LeVeque's pairwise update) for
the centring offset and the noise-variance floor.

Functions here are module-level and take only picklable arguments, so Ray can run them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np
from scipy.special import logsumexp

from . import _ppca


@dataclass
class Params:
    """MPPCA parameters: weights (M,), means (M, d), components (M, d, q) the W_i, noise_variance (M,)."""

    weights: np.ndarray
    means: np.ndarray
    components: np.ndarray
    noise_variance: np.ndarray

    def shifted(self, offset: np.ndarray) -> "Params":
        """The same mixture in coordinates x - offset (means minus offset)."""
        return Params(self.weights, self.means - offset, self.components, self.noise_variance)


@dataclass
class Moments:
    """Row count n, mean (d,) and total sum of squared deviations m2 = sum_n ||x_n - mean||^2."""

    n: int
    mean: np.ndarray
    m2: float

    def __add__(self, other: "Moments") -> "Moments":
        # Chan, Golub & LeVeque (1979): exact pairwise combination, no cancellation of large sums.
        n = self.n + other.n
        delta = other.mean - self.mean
        mean = self.mean + delta * (other.n / n)
        m2 = self.m2 + other.m2 + float(delta @ delta) * self.n * other.n / n
        return Moments(n, mean, m2)


@dataclass
class ShardStats:
    """The additive EM sums of a set of rows (module doc): n, loglik, r (M,), G (d, Mq+M), sq (M,)."""

    n: int
    loglik: float
    r: np.ndarray
    G: np.ndarray
    sq: np.ndarray

    def __add__(self, other: "ShardStats") -> "ShardStats":
        return ShardStats(self.n + other.n, self.loglik + other.loglik, self.r + other.r, self.G + other.G,
                          self.sq + other.sq)


def shard_moments(X: np.ndarray) -> Moments:
    """Moments of the rows of X (n, d) float64 (n >= 1)."""
    mean = X.mean(axis=0)
    E = X - mean
    return Moments(int(X.shape[0]), mean, float(np.einsum("ij,ij->", E, E)))


def shard_stats(X: np.ndarray, params: Params) -> ShardStats:
    """E-step on the rows of X (n, d) (centred like ``params``) and the M-step sums of those rows.

    One product X [W_1..W_M mu_1..mu_M] gives the log densities, the log-likelihood and the
    responsibilities R_ni (T&B eq. 21); one product X^T [R_i X W_i, R] gives the M-step sums.
    """
    sqn, XW, Xmu = _ppca.e_step_products(X, params.means, params.components)
    ll = _ppca.log_prob_from_products(sqn, XW, Xmu, params.weights, params.means, params.components,
                                      params.noise_variance)
    log_norm = logsumexp(ll, axis=1)
    resp = np.exp(ll - log_norm[:, None], out=ll)  # E-step posteriors, in place of ll
    r, G, sq = _ppca.m_step_sums(X, sqn, resp, XW)
    return ShardStats(int(X.shape[0]), float(log_norm.sum()), r, G, sq)


def reduce_sum(parts: Iterable):
    """Sum of ``parts`` in the given order (Moments or ShardStats); the order fixes the rounding."""
    total = None
    for p in parts:
        total = p if total is None else total + p
    if total is None:
        raise ValueError("MPPCA: no data (no shard yielded any rows)")
    return total


def m_step(stats: ShardStats, params: Params, var_floor: float) -> Params:
    """New parameters from the summed ``stats`` computed under ``params`` (T&B eqs. C.20-C.23)."""
    counts, means, comps, s2 = _ppca.m_step_from_sums(stats.r, stats.G, stats.sq, params.components,
                                                       params.noise_variance, var_floor)
    return Params(counts / counts.sum(), means, comps, s2)


def take_rows(X: np.ndarray) -> np.ndarray:
    """Identity: a shard's (selected) rows, for gathering the initialisation subsample."""
    return X
