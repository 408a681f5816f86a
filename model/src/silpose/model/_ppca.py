"""Private numerics of the mixture of probabilistic PCA (Tipping & Bishop 1999, "Mixtures of
probabilistic principal component analysers", Neural Computation 11(2)).

Notation (one component i): data dimension d, latent dimension q, loading matrix W (d, q),
mean mu (d,), isotropic noise variance s2 = sigma_i^2, model covariance C = W W^T + s2 I (d, d).
Nothing here ever forms a d x d matrix: every quantity goes through the q x q matrix
M = W^T W + s2 I (T&B eq. 6):

    log|C|         = (d - q) log s2 + log|M|                      (matrix determinant lemma)
    e^T C^-1 e     = (||e||^2 - z^T M^-1 z) / s2,  z = W^T e      (Woodbury identity)

Rows are processed in chunks of ``_CHUNK`` so that no (N, d) temporary is allocated per
component; all accumulations are float64.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular

_LOG_2PI = float(np.log(2.0 * np.pi))
_CHUNK = 2048  # rows per block: 2048 x 1657 float64 = 27 MB


def _chunks(n: int, size: int = _CHUNK):
    for start in range(0, n, size):
        yield slice(start, min(start + size, n))


def component_log_density(X: np.ndarray, mean: np.ndarray, W: np.ndarray, s2: float) -> np.ndarray:
    """Log density of N(mean, W W^T + s2 I) at each row of X.

    X (N, d) float64, mean (d,), W (d, q), s2 > 0 scalar. Returns (N,) float64.
    Uses log|C| = (d-q) log s2 + log|M| and e^T C^-1 e = (||e||^2 - z^T M^-1 z)/s2 (module doc).
    """
    n, d = X.shape
    q = W.shape[1]
    M = W.T @ W + s2 * np.eye(q)
    L = np.linalg.cholesky(M)
    logdet = (d - q) * np.log(s2) + 2.0 * np.sum(np.log(np.diag(L)))
    out = np.empty(n)
    for sl in _chunks(n):
        E = X[sl] - mean
        z = E @ W  # (b, q)
        y = solve_triangular(L, z.T, lower=True, check_finite=False)  # L^-1 z: z^T M^-1 z = ||y||^2
        maha = (np.einsum("ij,ij->i", E, E) - np.einsum("ij,ij->j", y, y)) / s2
        out[sl] = -0.5 * (d * _LOG_2PI + logdet + maha)
    return out


def weighted_log_prob(X, weights, means, components, noise_variance) -> np.ndarray:
    """log pi_i + log N(x_n | mu_i, C_i) for all rows and components.

    X (N, d), weights (M,), means (M, d), components (M, d, q), noise_variance (M,). Returns (N, M).
    """
    n = X.shape[0]
    m = weights.shape[0]
    out = np.empty((n, m))
    with np.errstate(divide="ignore"):
        log_w = np.log(weights)
    for i in range(m):
        out[:, i] = log_w[i] + component_log_density(X, means[i], components[i], float(noise_variance[i]))
    return out


def ppca_closed_form(X: np.ndarray, q: int, var_floor: float, rng: np.random.Generator):
    """Maximum-likelihood PPCA of the rows of X (T&B 1999 PPCA paper, eqs. 7-8).

    X (n, d) float64 with n >= 1. Returns mean (d,), W (d, q), s2 (float) with
    s2 = (sum of the d-q smallest covariance eigenvalues)/(d-q) and W = U_q (L_q - s2 I)^(1/2)
    (the arbitrary rotation R = I). The covariance is the 1/n (maximum-likelihood) one.
    Eigen-pairs come from the n x n Gram matrix when n < d, from the d x d scatter when d is small
    (<= 512), else from a randomized thin SVD (approximate; used only to initialise EM).
    """
    n, d = X.shape
    mean = X.mean(axis=0)
    E = X - mean
    total = float(np.einsum("ij,ij->", E, E)) / n  # tr S
    if n <= d and n <= 4096:
        G = E @ E.T / n  # (n, n) Gram: same nonzero eigenvalues as S
        lam, V = np.linalg.eigh(G)
        lam, V = lam[::-1], V[:, ::-1]
        k = min(q, n)
        lam_q = np.clip(lam[:k], 0.0, None)
        U = np.zeros((d, k))
        pos = lam_q > 1e-300
        U[:, pos] = (E.T @ V[:, :k][:, pos]) / np.sqrt(n * lam_q[pos])
    elif d <= 512:
        lam, U = np.linalg.eigh(E.T @ E / n)  # small d only
        lam, U = lam[::-1], U[:, ::-1]
        k = q
        lam_q, U = np.clip(lam[:k], 0.0, None), U[:, :k]
    else:
        from sklearn.utils.extmath import randomized_svd

        k = q
        _, sv, Vt = randomized_svd(E, q, n_oversamples=20, n_iter=6,
                                   random_state=int(rng.integers(2**31 - 1)))
        lam_q, U = sv**2 / n, Vt.T
    s2 = max((total - float(lam_q.sum())) / (d - q), var_floor)
    W = np.zeros((d, q))
    W[:, :k] = U * np.sqrt(np.clip(lam_q - s2, 0.0, None))
    return mean, W, s2


def m_step_component(X, resp_i, W, s2, var_floor):
    """One EM update of a single component (T&B 1999 Appendix C, eqs. C.20-C.23 / 80-84).

    X (N, d), resp_i (N,) responsibilities R_ni, W (d, q) and s2 the current parameters.
    Returns (n_i, mu_new (d,), W_new (d, q), s2_new):
        n_i  = sum_n R_ni,   mu_new = sum_n R_ni x_n / n_i
        S W  = (1/n_i) sum_n R_ni (x_n - mu_new) ((x_n - mu_new)^T W)          (never S itself)
        W_new = S W (s2 I + M^-1 W^T S W)^-1,                 M = W^T W + s2 I
        s2_new = (tr S - tr(S W M^-1 W_new^T)) / d
    """
    n, d = X.shape
    q = W.shape[1]
    n_i = max(float(resp_i.sum()), 10.0 * np.finfo(float).eps)
    mu = (resp_i @ X) / n_i
    SW = np.zeros((d, q))
    trS = 0.0
    for sl in _chunks(n):
        E = X[sl] - mu
        r = resp_i[sl]
        Z = E @ W  # (b, q)
        SW += E.T @ (Z * r[:, None])
        trS += float(r @ np.einsum("ij,ij->i", E, E))
    SW /= n_i
    trS /= n_i
    M = W.T @ W + s2 * np.eye(q)
    cM = cho_factor(M, check_finite=False)
    MinvWtSW = cho_solve(cM, W.T @ SW, check_finite=False)  # M^-1 W^T S W  (q, q)
    A = s2 * np.eye(q) + MinvWtSW
    W_new = np.linalg.solve(A.T, SW.T).T  # S W A^-1
    SWMinv = cho_solve(cM, SW.T, check_finite=False).T  # S W M^-1  (d, q)
    s2_new = (trS - float(np.einsum("ij,ij->", SWMinv, W_new))) / d
    return n_i, mu, W_new, max(s2_new, var_floor)
