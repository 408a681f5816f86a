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

from dataclasses import dataclass, field
from typing import Iterable

import numpy as np
from scipy.special import logsumexp

from . import _ppca
from .threads import one_blas_thread


@dataclass
class Params:
    """MPPCA parameters: weights (M,), means (M, d), components (M, d, q) the W_i, noise_variance (M,)."""

    weights: np.ndarray
    means: np.ndarray
    components: np.ndarray
    noise_variance: np.ndarray
    factors: list | None = field(default=None, repr=False, compare=False)  # density_factors() once computed

    def shifted(self, offset: np.ndarray) -> "Params":
        """The same mixture in coordinates x - offset (means minus offset)."""
        return Params(self.weights, self.means - offset, self.components, self.noise_variance, self.factors)

    def density_factors(self) -> list[tuple[np.ndarray, float]]:
        """Per component :func:`silpose.model._ppca.density_factors` (L^-T, log|C_i|), computed on first use and
        kept: every block of a pass uses the same ones."""
        if self.factors is None:
            self.factors = [_ppca.density_factors(W, float(s2)) for W, s2 in zip(self.components, self.noise_variance)]
        return self.factors


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
    """The additive EM sums of a set of rows (module doc): n, loglik, r (M,), G (d, Mq+M), sq (M,).

    ``about_means``: the sums are of x - mu_i for each component i's current mean (the sparse E-step)
    instead of x: G_i = sum_n R_ni (x_n - mu_i)(x_n - mu_i)^T W_i, g_i = sum_n R_ni (x_n - mu_i),
    sq_i = sum_n R_ni ||x_n - mu_i||^2."""

    n: int
    loglik: float
    r: np.ndarray
    G: np.ndarray
    sq: np.ndarray
    about_means: bool = False

    def __add__(self, other: "ShardStats") -> "ShardStats":
        if self.about_means != other.about_means:
            raise ValueError("MPPCA: cannot add EM sums about the means to sums about the origin")
        return ShardStats(self.n + other.n, self.loglik + other.loglik, self.r + other.r, self.G + other.G,
                          self.sq + other.sq, self.about_means)


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
    factors = params.density_factors()
    with one_blas_thread():  # M small (rows, q) x (q, q) products
        ll = _ppca.log_prob_from_products(sqn, XW, Xmu, params.weights, params.means, params.components,
                                          params.noise_variance, factors)
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
                                                       params.noise_variance, var_floor,
                                                       centres=params.means if stats.about_means else None)
    return Params(counts / counts.sum(), means, comps, s2)


def take_rows(X: np.ndarray) -> np.ndarray:
    """Identity: a shard's (selected) rows, for gathering the initialisation subsample."""
    return X


# ---------------------------------------------------------------------------- the sparse E-step
# For M in the hundreds a row's posterior sits on a handful of components (at d ~ 1,700 the log
# densities of different components differ by hundreds of nats). The sparse E-step scores each row
# under only K candidate components, chosen by a gate (the dense E-step products in float32, top K
# per row) at the first iteration and every ``refresh`` iterations, and kept in between (Neal &
# Hinton 1998, "A view of the EM algorithm that justifies incremental, sparse, and other variants").
# Within the candidates, components more than ``threshold`` nats below the row's best get no
# responsibility. The per-candidate products x - mu_i and (x - mu_i)^T W_i run in float32; squared
# norms, log densities and every sum are float64. The sums are taken about each component's current
# mean (``about_means``), so the M-step never subtracts large nearly equal float64 numbers.


@dataclass(frozen=True)
class SparseEStep:
    """Settings of the sparse E-step: ``n_candidates`` K components per row, the responsibility
    ``threshold`` (nats below the row's best), and the gate's ``refresh`` period (iterations)."""

    n_candidates: int = 4
    threshold: float = 30.0
    refresh: int = 10


_GATE_ROWS = 1024  # rows per block of the gate's dense float32 product (rows x M (q + 1) values)


def gate_candidates(X: np.ndarray, params: Params, k: int) -> np.ndarray:
    """(n, k) int32: the k components of highest weighted log density per row of X (n, d), scored from the
    dense E-step products computed in float32 (an approximation used only to rank the components)."""
    m = params.weights.shape[0]
    n = X.shape[0]
    if k >= m:
        return np.broadcast_to(np.arange(m, dtype=np.int32), (n, m)).copy()
    out = np.empty((n, k), dtype=np.int32)
    means32, comps32 = params.means.astype(np.float32), params.components.astype(np.float32)
    for start in range(0, n, _GATE_ROWS):
        B = X[start:start + _GATE_ROWS]
        sqn = np.einsum("ij,ij->i", B, B)
        _, XW, Xmu = _ppca.e_step_products(B.astype(np.float32), means32, comps32, with_sqn=False)
        factors = params.density_factors()
        with one_blas_thread():  # M small (rows, q) x (q, q) products
            ll = _ppca.log_prob_from_products(sqn, XW.astype(np.float64), Xmu.astype(np.float64), params.weights,
                                              params.means, params.components, params.noise_variance, factors)
        out[start:start + B.shape[0]] = np.argpartition(-ll, k - 1, axis=1)[:, :k]
    return out


def shard_stats_sparse(X: np.ndarray, candidates, params: Params, cfg: SparseEStep):
    """The sparse E-step (section comment above) on the rows of X (n, d) and the M-step sums of those
    rows about the current means. ``candidates`` (n, K) int32 or None (gate now). Returns
    (ShardStats with ``about_means``, the candidates used)."""
    n, d = X.shape
    m, _, q = params.components.shape
    cand = gate_candidates(X, params, cfg.n_candidates) if candidates is None else np.asarray(candidates)
    k = cand.shape[1]
    flat = cand.ravel()
    order = np.argsort(flat, kind="stable")  # the (row, slot) pairs grouped by component
    bounds = np.concatenate([[0], np.cumsum(np.bincount(flat, minlength=m))])
    ll, SQ = np.empty(n * k), np.empty(n * k)
    Z = np.empty((n * k, q), dtype=np.float32)
    comps32 = params.components.astype(np.float32)
    with np.errstate(divide="ignore"):
        log_w = np.log(params.weights)
    for i in range(m):
        pairs = order[bounds[i]:bounds[i + 1]]
        if not pairs.size:
            continue
        E = X[pairs // k] - params.means[i]  # float64: exact squared norms
        sq_e = SQ[pairs] = np.einsum("ij,ij->i", E, E)
        z = E.astype(np.float32) @ comps32[i]
        Z[pairs] = z
        ll[pairs] = log_w[i] + _ppca.log_density_terms(sq_e, z.astype(np.float64), params.components[i],
                                                        float(params.noise_variance[i]), params.density_factors()[i])
    ll = ll.reshape(n, k)
    best = ll.max(axis=1, keepdims=True)
    ll[ll < best - cfg.threshold] = -np.inf
    log_norm = logsumexp(ll, axis=1)
    resp = np.exp(ll - log_norm[:, None]).ravel()
    r, sq = np.zeros(m), np.zeros(m)
    G = np.zeros((d, m * q + m))
    X32 = X.astype(np.float32)
    means32 = params.means.astype(np.float32)
    for i in range(m):
        pairs = order[bounds[i]:bounds[i + 1]]
        pairs = pairs[resp[pairs] > 0]
        if not pairs.size:
            continue
        R = resp[pairs]
        E = X32[pairs // k] - means32[i]
        rhs = np.empty((pairs.size, q + 1), dtype=np.float32)
        np.multiply(Z[pairs], R[:, None], out=rhs[:, :q])
        rhs[:, q] = R
        prod = E.T @ rhs  # (d, q + 1): sum R (x - mu_i)(x - mu_i)^T W_i and sum R (x - mu_i)
        G[:, i * q:(i + 1) * q] = prod[:, :q]
        G[:, m * q + i] = prod[:, q]
        r[i] = R.sum()
        sq[i] = R @ SQ[pairs]
    return ShardStats(int(n), float(log_norm.sum()), r, G, sq, about_means=True), cand
