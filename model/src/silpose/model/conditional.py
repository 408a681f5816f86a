"""Exact Gaussian conditioning of a mixture of PPCA on any subset of observed dimensions.

A vector x (d,) is split into an observed block a (d_obs dims, indices ``obs``) and a missing
block b (d_miss dims). The observed values carry extra zero-mean Gaussian noise of variance s_j^2
(scalar or one per observed dim). Per component i, with D = diag(sigma_i^2 + s_j^2) (d_obs,):

    C_aa = W_a W_a^T + D,     K = I_q + W_a^T D^-1 W_a                     (q, q)
    C_aa^-1 = D^-1 - D^-1 W_a K^-1 W_a^T D^-1                               (Woodbury)
    log|C_aa| = sum_j log D_j + log|K|                                       (determinant lemma)
    x_hat = K^-1 W_a^T D^-1 (a - mu_a)                                       (latent posterior mean)
    E[b | a, i] = mu_b + W_b x_hat,   Cov[b | a, i] = W_b K^-1 W_b^T + sigma_i^2 I
    p(i | a) ∝ pi_i N(a; mu_a, C_aa)

For scalar noise s^2 this is DESIGN §4: tau^2 = sigma^2 + s^2, M_a = W_a^T W_a + tau^2 I = tau^2 K,
x_hat = M_a^-1 W_a^T (a - mu_a), Cov = tau^2 W_b M_a^-1 W_b^T + sigma^2 I. The mixture posterior
mean is sum_i p(i|a) E[b|a,i]; its covariance follows the law of total variance. Missing dims
are dropped from every product (marginalised), never zero-filled. Cost O(N d_obs q M).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_LOG_2PI = float(np.log(2.0 * np.pi))
_CHUNK = 4096


@dataclass
class ConditionalResult:
    """Posterior of the missing block given the observed one (N rows, M components).

    mean (N, d_miss) mixture posterior mean E[b | a]; best_mean (N, d_miss) the mean under the
    most probable component; component_means (N, M, d_miss); responsibilities (N, M) p(i | a);
    variance (N, d_miss) diagonal of the mixture posterior covariance; log_marginal (N,) log p(a)
    in nats; missing: the missing dims as indices (d_miss,) for ``condition`` or as a (N, d) bool
    mask for ``condition_rows``; cov (N, d_miss, d_miss) and component_cov (M, d_miss, d_miss)
    only when ``return_cov=True`` (``condition`` only).
    """

    mean: np.ndarray
    best_mean: np.ndarray
    component_means: np.ndarray
    responsibilities: np.ndarray
    variance: np.ndarray
    log_marginal: np.ndarray
    missing: np.ndarray
    cov: np.ndarray | None = None
    component_cov: np.ndarray | None = None


def _logsumexp_rows(a: np.ndarray) -> np.ndarray:
    """log sum_j exp(a_ij) per row of a (N, M) (rows of -inf give -inf)."""
    mx = np.max(a, axis=1, keepdims=True)
    mx = np.where(np.isfinite(mx), mx, 0.0)
    with np.errstate(divide="ignore"):
        return np.log(np.sum(np.exp(a - mx), axis=1)) + mx[:, 0]


def _params(model):
    try:
        w = np.asarray(model.weights_, dtype=np.float64)
        mu = np.asarray(model.means_, dtype=np.float64)
        W = np.asarray(model.components_, dtype=np.float64)
        s2 = np.asarray(model.noise_variance_, dtype=np.float64)
    except AttributeError as exc:
        raise TypeError("condition: model_or_params needs weights_, means_, components_ and noise_variance_ "
                        "(a fitted MPPCA)") from exc
    if W.ndim != 3 or mu.shape != W.shape[:2] or w.shape != (W.shape[0],) or s2.shape != (W.shape[0],):
        raise ValueError(f"condition: inconsistent parameter shapes weights_ {w.shape}, means_ {mu.shape}, "
                         f"components_ {W.shape}, noise_variance_ {s2.shape}")
    if np.any(s2 <= 0) or np.any(w < 0):
        raise ValueError("condition: noise_variance_ must be > 0 and weights_ >= 0")
    return w, mu, W, s2


def _observed_index(observed, d: int) -> np.ndarray:
    obs = np.asarray(observed)
    if obs.dtype == bool:
        if obs.shape != (d,):
            raise ValueError(f"condition: boolean 'observed' mask must have shape ({d},), got {obs.shape}")
        return np.flatnonzero(obs)
    if obs.ndim != 1 or (obs.size and not np.issubdtype(obs.dtype, np.integer)):
        raise ValueError("condition: 'observed' must be a (d,) bool mask or a 1-D integer index array")
    obs = obs.astype(np.intp)
    if obs.size and (obs.min() < 0 or obs.max() >= d):
        raise ValueError(f"condition: 'observed' indices must lie in [0, {d}), got [{obs.min()}, {obs.max()}]")
    if np.unique(obs).size != obs.size:
        raise ValueError("condition: 'observed' index array has repeated indices")
    return obs


class Conditioner:
    """Precomputed conditioning for one observed pattern; call it on batches of observations.

    model_or_params: a fitted MPPCA or anything with weights_ (M,), means_ (M, d), components_
    (M, d, q), noise_variance_ (M,). observed: (d,) bool mask or index array of the observed dims.
    noise_variance: observation-noise variance s^2 >= 0, a scalar or (d_obs,) per observed dim (in
    the units of the data squared). All q x q factorisations are done here once; ``__call__``
    costs O(N d_obs q M).
    """

    def __init__(self, model_or_params, observed, noise_variance=0.0):
        w, mu, W, s2 = _params(model_or_params)
        m, d, q = W.shape
        self.obs = _observed_index(observed, d)
        mask = np.zeros(d, dtype=bool)
        mask[self.obs] = True
        self.miss = np.flatnonzero(~mask)
        noise = np.asarray(noise_variance, dtype=np.float64)
        if noise.ndim == 0:
            noise = np.full(self.obs.size, float(noise))
        if noise.shape != (self.obs.size,):
            raise ValueError(f"condition: noise_variance must be a scalar or have shape ({self.obs.size},) "
                             f"(one per observed dim), got {noise.shape}")
        if not np.all(np.isfinite(noise)) or np.any(noise < 0):
            raise ValueError("condition: noise_variance must be finite and >= 0")
        self.n_components, self.d, self.q = m, d, q
        with np.errstate(divide="ignore"):
            self.log_w = np.log(w)
        self.s2 = s2
        self.scalar_noise = bool(np.all(noise == noise[:1])) if noise.size else True
        # Observations are centred on the mixture mean of the observed dims, so that the expanded
        # quadratic forms below keep their precision.
        mu_a = mu[:, self.obs]
        self.ref = w @ mu_a
        mu_c = mu_a - self.ref  # (M, d_obs)
        self.mu_b = mu[:, self.miss]  # (M, d_miss)
        Wa, Wb = W[:, self.obs, :], W[:, self.miss, :]
        self.invD = 1.0 / (s2[:, None] + noise[None, :])  # (M, d_obs) D_i^-1 diagonal
        G = Wa * self.invD[:, :, None]  # D^-1 W_a  (M, d_obs, q)
        # 2-D products per component (numpy's stacked matmul on transposed views skips BLAS)
        L = np.linalg.cholesky(np.eye(q) + np.stack([Wa[i].T @ G[i] for i in range(m)]))  # K = I + W_a^T D^-1 W_a
        Linv = np.linalg.inv(L)
        self.Kinv = np.stack([Linv[i].T @ Linv[i] for i in range(m)])  # (M, q, q)
        self.H = np.stack([self.Kinv[i] @ Wb[i].T for i in range(m)])  # K^-1 W_b^T  (M, q, d_miss)
        self.V = np.stack([Wb[i] @ Linv[i].T for i in range(m)])  # W_b L^-T: W_b K^-1 W_b^T = V V^T
        self.logdet = -np.log(self.invD).sum(axis=1) + 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
        # One product per batch: x_c [G_1 .. G_M  (mu_c,i * D_i^-1)_i]  (d_obs, M q + M)
        self.B = np.concatenate([G.transpose(1, 0, 2).reshape(self.obs.size, m * q), (mu_c * self.invD).T], axis=1)
        self.c_u = np.einsum("md,mdq->mq", mu_c, G)  # W_a^T D^-1 mu_c  (M, q)
        self.c_quad = np.einsum("md,md->m", mu_c * self.invD, mu_c)  # mu_c^T D^-1 mu_c  (M,)
        self.invD_scalar = self.invD[:, 0] if self.obs.size else np.zeros(m)  # used when noise is scalar
        self.comp_var = np.einsum("mkq,mkq->mk", self.V, self.V) + s2[:, None]  # diag Cov[b | a, i]  (M, d_miss)

    def component_cov(self) -> np.ndarray:
        """Per-component posterior covariance of the missing block (M, d_miss, d_miss):
        W_b K^-1 W_b^T + sigma^2 I (independent of the observed values)."""
        return np.matmul(self.V, self.V.transpose(0, 2, 1)) + self.s2[:, None, None] * np.eye(self.miss.size)

    def __call__(self, X_obs, return_cov: bool = False) -> ConditionalResult:
        """Condition on observations X_obs (N, d_obs) (or (d_obs,) for one row).

        With e = a - mu_a = x_c - mu_c (x_c = a - ref): u = W_a^T D^-1 e = x_c^T G - c_u,
        e^T D^-1 e = x_c^T D^-1 x_c - 2 x_c^T D^-1 mu_c + c_quad, Mahalanobis = e^T D^-1 e - u^T K^-1 u,
        E[b | a, i] = mu_b + H^T u.
        """
        X = np.asarray(X_obs, dtype=np.float64)
        if X.ndim == 1:
            X = X[None, :]
        if X.ndim != 2 or X.shape[1] != self.obs.size:
            raise ValueError(f"condition: X_obs must have shape (N, {self.obs.size}) (one column per observed "
                             f"dim), got {np.shape(X_obs)}")
        if not np.all(np.isfinite(X)):
            raise ValueError("condition: X_obs contains NaN or inf; use condition_rows for per-row missing dims")
        n, m, q, dm = X.shape[0], self.n_components, self.q, self.miss.size
        logp = np.empty((n, m))
        cmeans = np.empty((n, m, dm))
        const = self.log_w - 0.5 * (self.obs.size * _LOG_2PI + self.logdet)
        for sl in (slice(s, min(s + _CHUNK, n)) for s in range(0, n, _CHUNK)):
            Xc = X[sl] - self.ref
            P = Xc @ self.B
            if self.scalar_noise:
                quad = np.einsum("ij,ij->i", Xc, Xc)[:, None] * self.invD_scalar
            else:
                quad = (Xc * Xc) @ self.invD.T
            eDe = quad - 2.0 * P[:, m * q:] + self.c_quad  # (b, M)
            for i in range(m):
                U = P[:, i * q:(i + 1) * q] - self.c_u[i]  # u = W_a^T D^-1 e  (b, q), contiguous
                uKu = np.einsum("ij,ij->i", U @ self.Kinv[i], U)
                logp[sl, i] = const[i] - 0.5 * (eDe[:, i] - uKu)
                cmeans[sl, i] = U @ self.H[i] + self.mu_b[i]
        log_marg = _logsumexp_rows(logp)
        resp = np.exp(logp - log_marg[:, None])
        mean = np.einsum("nm,nmk->nk", resp, cmeans)
        best = cmeans[np.arange(n), np.argmax(resp, axis=1)]
        dev = cmeans - mean[:, None, :]
        variance = resp @ self.comp_var + np.einsum("nm,nmk->nk", resp, dev * dev)  # law of total variance
        cov = ccov = None
        if return_cov:
            ccov = self.component_cov()
            cov = np.einsum("nm,mij->nij", resp, ccov) + np.einsum("nm,nmi,nmj->nij", resp, dev, dev)
        return ConditionalResult(mean=mean, best_mean=best, component_means=cmeans, responsibilities=resp,
                                 variance=variance, log_marginal=log_marg, missing=self.miss, cov=cov,
                                 component_cov=ccov)


def condition(model_or_params, X_obs, observed, noise_variance=0.0, return_cov: bool = False) -> ConditionalResult:
    """Posterior of the unobserved dims of a mixture of PPCA given the observed ones.

    model_or_params: fitted MPPCA or object with weights_, means_, components_, noise_variance_.
    X_obs (N, d_obs): observed values, columns in the order of ``observed``.
    observed: (d,) bool mask or (d_obs,) integer index array. noise_variance: scalar or (d_obs,)
    observation-noise variance added to the model noise of the observed dims.
    Returns a ConditionalResult (missing dims marginalised exactly, module doc).
    """
    return Conditioner(model_or_params, observed, noise_variance)(X_obs, return_cov=return_cov)


def condition_rows(model_or_params, X, noise_variance=0.0) -> ConditionalResult:
    """Condition each row on its own finite entries; NaN marks a missing dim.

    X (N, d) with NaN where a dim is missing (rows may miss different dims; rows are grouped
    by NaN pattern and each group is conditioned once). noise_variance: scalar or (d,) per dim
    (only the observed entries of each row are used). Returns a ConditionalResult whose arrays
    span all d dims: ``mean``, ``best_mean`` (N, d) and ``component_means`` (N, M, d) hold the
    observed values at observed dims and the posterior means at missing ones; ``variance`` (N, d)
    is 0 at observed dims; ``missing`` is the (N, d) bool mask.
    """
    w, mu, W, s2 = _params(model_or_params)
    m, d, _ = W.shape
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != d:
        raise ValueError(f"condition_rows: X must have shape (N, {d}) with NaN for missing dims, got {X.shape}")
    if np.any(np.isinf(X)):
        raise ValueError("condition_rows: X contains inf; mark missing dims with NaN")
    noise = np.asarray(noise_variance, dtype=np.float64)
    if noise.ndim != 0 and noise.shape != (d,):
        raise ValueError(f"condition_rows: noise_variance must be a scalar or have shape ({d},), got {noise.shape}")
    miss = np.isnan(X)
    n = X.shape[0]
    mean = np.where(miss, 0.0, X)
    best = mean.copy()
    cmeans = np.repeat(mean[:, None, :], m, axis=1)
    variance = np.zeros((n, d))
    resp = np.empty((n, m))
    log_marg = np.empty(n)
    patterns, group = np.unique(miss, axis=0, return_inverse=True)
    group = group.reshape(-1)
    params = (w, mu, W, s2)
    for g, pattern in enumerate(patterns):
        rows = np.flatnonzero(group == g)
        obs = np.flatnonzero(~pattern)
        cond = Conditioner(_Params(*params), obs, noise if noise.ndim == 0 else noise[obs])
        res = cond(X[np.ix_(rows, obs)])
        mcols = cond.miss
        mean[np.ix_(rows, mcols)] = res.mean
        best[np.ix_(rows, mcols)] = res.best_mean
        cmeans[rows[:, None, None], np.arange(m)[None, :, None], mcols[None, None, :]] = res.component_means
        variance[np.ix_(rows, mcols)] = res.variance
        resp[rows] = res.responsibilities
        log_marg[rows] = res.log_marginal
    return ConditionalResult(mean=mean, best_mean=best, component_means=cmeans, responsibilities=resp,
                             variance=variance, log_marginal=log_marg, missing=miss)


@dataclass
class _Params:
    weights_: np.ndarray
    means_: np.ndarray
    components_: np.ndarray
    noise_variance_: np.ndarray


__all__ = ["ConditionalResult", "Conditioner", "condition", "condition_rows"]
