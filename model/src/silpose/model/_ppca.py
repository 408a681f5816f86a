"""Private numerics of the mixture of probabilistic PCA (Tipping & Bishop 1999, "Mixtures of
probabilistic principal component analysers", Neural Computation 11(2)).

Notation (one component i): data dimension d, latent dimension q, loading matrix W (d, q),
mean mu (d,), isotropic noise variance s2 = sigma_i^2, model covariance C = W W^T + s2 I (d, d).
EM and the densities never form a d x d matrix (only the PPCA initialisation does, and only when
d <= 512): every quantity goes through the q x q matrix M = W^T W + s2 I (T&B eq. 6):

    log|C|         = (d - q) log s2 + log|M|                      (matrix determinant lemma)
    e^T C^-1 e     = (||e||^2 - z^T M^-1 z) / s2,  z = W^T e      (Woodbury identity)

EM touches the data through two matrix products per iteration, each shared by all components:
X [W_1 .. W_M mu_1 .. mu_M] (E-step) and X^T [R_1 X W_1 .. R_M X W_M R] (M-step), so no (N, d)
temporary is allocated per component; all accumulations are float64. The q x q algebra uses
numpy.linalg only: alternating numpy's and scipy's separate OpenBLAS thread pools inside the
EM loop stalls badly when other processes load the cores.
"""

from __future__ import annotations

import numpy as np

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
    out = np.empty(X.shape[0])
    for sl in _chunks(X.shape[0]):
        E = X[sl] - mean
        out[sl] = log_density_terms(np.einsum("ij,ij->i", E, E), E @ W, W, s2)
    return out


def density_factors(W: np.ndarray, s2: float) -> tuple[np.ndarray, float]:
    """The per-component constants of :func:`log_density_terms` for W (d, q), s2 > 0: (L^-T (q, q), log|C|),
    with M = W^T W + s2 I = L L^T and log|C| = (d - q) log s2 + log|M| (module doc).

    They depend on the parameters only: an EM pass computes them once per component
    (``Params.density_factors``), not once per block of rows (small LAPACK calls cost ~10-100 us each under
    OpenBLAS threading, which made them the larger part of a block's E-step at M 60, q 40)."""
    d, q = W.shape
    L = np.linalg.cholesky(W.T @ W + s2 * np.eye(q))
    logdet = (d - q) * np.log(s2) + 2.0 * np.sum(np.log(np.diag(L)))
    return np.linalg.inv(L).T, float(logdet)


def log_density_terms(sqn, z, W, s2, factors: tuple[np.ndarray, float] | None = None):
    """log N(e; 0, W W^T + s2 I) from ||e||^2 (N,) and z = W^T e (N, q); W (d, q); ``factors``: W's
    :func:`density_factors` when already computed."""
    d = W.shape[0]
    inv_lt, logdet = density_factors(W, s2) if factors is None else factors
    y = z @ inv_lt  # rows L^-1 z_n, so z^T M^-1 z = ||y||^2
    maha = (sqn - np.einsum("ij,ij->i", y, y)) / s2
    return -0.5 * (d * _LOG_2PI + logdet + np.maximum(maha, 0.0))


def e_step_products(X: np.ndarray, means: np.ndarray, components: np.ndarray, with_sqn: bool = True):
    """The data products every E-step and M-step needs, from ONE matrix product X [W_1..W_M mu_1..mu_M].

    X (N, d), means (M, d), components (M, d, q). Returns sqn (N,) = ||x_n||^2 (None unless with_sqn),
    XW (N, M, q) = x_n^T W_i, Xmu (N, M) = x_n^T mu_i. Cost O(N d (M q + M)).
    """
    m, d, q = components.shape
    B = np.concatenate([components.transpose(1, 0, 2).reshape(d, m * q), means.T], axis=1)  # (d, Mq+M)
    P = X @ B
    sqn = np.einsum("ij,ij->i", X, X) if with_sqn else None
    return sqn, P[:, : m * q].reshape(-1, m, q), P[:, m * q:]


def log_prob_from_products(sqn, XW, Xmu, weights, means, components, noise_variance,
                           factors: list | None = None) -> np.ndarray:
    """log pi_i + log N(x_n | mu_i, C_i) (N, M) from ``e_step_products`` (shapes there); ``factors``: the
    components' :func:`density_factors` when already computed (else computed here). EM calls it inside
    ``silpose.model.threads.one_blas_thread`` (``silpose.model._em``).

    With e = x - mu_i: ||e||^2 = ||x||^2 - 2 x^T mu_i + ||mu_i||^2 and W_i^T e = W_i^T x - W_i^T mu_i.
    """
    m = weights.shape[0]
    out = np.empty((sqn.shape[0], m))
    with np.errstate(divide="ignore"):
        log_w = np.log(weights)
    for i in range(m):
        mu, W = means[i], components[i]
        sq_e = sqn - 2.0 * Xmu[:, i] + mu @ mu
        z = XW[:, i, :] - mu @ W
        out[:, i] = log_w[i] + log_density_terms(sq_e, z, W, float(noise_variance[i]),
                                                 None if factors is None else factors[i])
    return out


def weighted_log_prob(X, weights, means, components, noise_variance) -> np.ndarray:
    """log pi_i + log N(x_n | mu_i, C_i) for all rows and components.

    X (N, d), weights (M,), means (M, d), components (M, d, q), noise_variance (M,). Returns (N, M).
    Rows are shifted by the mixture mean first (chunks of ``_CHUNK`` rows) so that the expanded
    ||x - mu||^2 does not lose precision to a large common offset.
    """
    ref = weights @ means
    out = np.empty((X.shape[0], weights.shape[0]))
    m_c = means - ref
    for sl in _chunks(X.shape[0]):
        out[sl] = log_prob_from_products(*e_step_products(X[sl] - ref, m_c, components), weights, m_c,
                                         components, noise_variance)
    return out


def _spd_inverse(M: np.ndarray) -> np.ndarray:
    """Inverse of a small symmetric positive-definite matrix (q, q) through its Cholesky factor."""
    Linv = np.linalg.inv(np.linalg.cholesky(M))
    return Linv.T @ Linv


def m_step_sums(X, sqn, resp, XW):
    """The data sums of one M-step, additive over row blocks (T&B 1999 Appendix C).

    X (N, d), sqn (N,) = ||x_n||^2, resp (N, M) responsibilities R_ni, XW (N, M, q) = x_n^T W_i for
    the CURRENT W_i (from the E-step). Returns
        r (M,)           sum_n R_ni
        G (d, Mq + M)    X^T [R_1 X W_1 .. R_M X W_M  R]: sum_n R_ni x_n (x_n^T W_i) and sum_n R_ni x_n
        sq (M,)          sum_n R_ni ||x_n||^2
    from ONE matrix product; never a d x d matrix. Sums over row blocks add up to the sums over all rows.
    """
    n = X.shape[0]
    m, q = XW.shape[1], XW.shape[2]
    rhs = np.concatenate([(XW * resp[:, :, None]).reshape(n, m * q), resp], axis=1)  # (N, Mq+M)
    return resp.sum(axis=0), X.T @ rhs, resp.T @ sqn


def m_step_from_sums(r, G, sq, components, noise_variance, var_floor, centres=None):
    """One EM update of every component from the sums of ``m_step_sums`` (T&B 1999 eqs. C.20-C.23).

    r (M,), G (d, Mq+M), sq (M,) summed over all rows; components (M, d, q) and noise_variance (M,)
    the current parameters (those the sums were computed with). Returns n (M,) (r floored at
    10 eps), means (M, d), W_new (M, d, q), s2_new (M,). For each i, with n_i = sum_n R_ni and
    mu_i = sum_n R_ni x_n / n_i:
        S W  = (1/n_i) sum_n R_ni (x_n - mu_i)(x_n - mu_i)^T W = (1/n_i) G_i - mu_i (mu_i^T W)
        tr S = (1/n_i) sum_n R_ni ||x_n||^2 - ||mu_i||^2
        W_new = S W (s2 I + M^-1 W^T S W)^-1,            M = W^T W + s2 I
        s2_new = (tr S - tr(S W M^-1 W_new^T)) / d
    S itself (d x d) is never formed: only d x q and q x q matrices.
    ``centres`` (M, d) or None: the sums were taken about these points c_i (x_n - c_i for component i,
    ``silpose.model._em.shard_stats_sparse``); the formulas above then give the mean's offset from c_i,
    and mu_i = c_i + offset.
    """
    m, d, q = components.shape
    counts = np.maximum(np.asarray(r, dtype=np.float64), 10.0 * np.finfo(float).eps)
    means = (G[:, m * q:] / counts).T
    offsets = means  # the formulas' mu_i, relative to the centres
    W_new = np.empty_like(components)
    s2_new = np.empty(m)
    eye = np.eye(q)
    for i in range(m):
        W, s2, mu = components[i], float(noise_variance[i]), means[i]
        SW = G[:, i * q:(i + 1) * q] / counts[i] - np.outer(mu, mu @ W)
        trS = float(sq[i]) / counts[i] - float(mu @ mu)
        Minv = _spd_inverse(W.T @ W + s2 * eye)
        A = s2 * eye + Minv @ (W.T @ SW)  # s2 I + M^-1 W^T S W
        W_new[i] = SW @ np.linalg.inv(A)  # S W A^-1
        s2_new[i] = max((trS - float(np.einsum("ij,ij->", SW @ Minv, W_new[i]))) / d, var_floor)
    if centres is not None:
        means = centres + offsets
    return counts, means, W_new, s2_new


def m_step(X, sqn, resp, XW, components, noise_variance, var_floor):
    """One EM update on the rows of X: ``m_step_from_sums(*m_step_sums(X, sqn, resp, XW), ...)``.

    X (N, d) (best centred on the data mean), sqn (N,), resp (N, M), XW (N, M, q), components
    (M, d, q), noise_variance (M,). Returns n (M,), means (M, d), W_new (M, d, q), s2_new (M,).
    """
    return m_step_from_sums(*m_step_sums(X, sqn, resp, XW), components, noise_variance, var_floor)


def _randomized_top_eigen(E: np.ndarray, k: int, rng: np.random.Generator, oversample: int = 10,
                          n_power: int = 2):
    """Approximate top-k eigenpairs of E^T E for E (n, d), numpy only (Halko, Martinsson & Tropp
    2011, algorithms 4.3/4.4 with QR re-orthonormalisation). Returns (eigenvalues (k,), U (d, k))."""
    Q, _ = np.linalg.qr(E @ rng.standard_normal((E.shape[1], k + oversample)))
    for _ in range(n_power):
        Q, _ = np.linalg.qr(E.T @ Q)
        Q, _ = np.linalg.qr(E @ Q)
    B = Q.T @ E  # (k + p, d), E ~ Q B
    lam, V = np.linalg.eigh(B @ B.T)
    lam, V = lam[::-1][:k], V[:, ::-1][:, :k]
    U = B.T @ V / np.sqrt(np.clip(lam, 1e-300, None))
    return np.clip(lam, 0.0, None), U


def ppca_closed_form(X: np.ndarray, q: int, var_floor: float, rng: np.random.Generator):
    """Maximum-likelihood PPCA of the rows of X (T&B 1999 PPCA paper, eqs. 7-8).

    X (n, d) float64 with n >= 1. Returns mean (d,), W (d, q), s2 (float) with
    s2 = (sum of the d-q smallest covariance eigenvalues)/(d-q) and W = U_q (L_q - s2 I)^(1/2)
    (the arbitrary rotation R = I). The covariance is the 1/n (maximum-likelihood) one.
    Eigen-pairs come from the n x n Gram matrix when n <= d (and n <= 4096), from the d x d scatter
    when d is small (<= 512), else from a randomized range finder (approximate; used only to
    initialise EM).
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
        k = q
        lam_q, U = _randomized_top_eigen(E, q, rng)
        lam_q = lam_q / n
    s2 = max((total - float(lam_q.sum())) / (d - q), var_floor)
    W = np.zeros((d, q))
    W[:, :k] = U * np.sqrt(np.clip(lam_q - s2, 0.0, None))
    return mean, W, s2


def dof_noise_factor(counts: np.ndarray, d: int, q: int) -> tuple[np.ndarray, np.ndarray]:
    """Degrees-of-freedom correction of maximum-likelihood PPCA noise variances.

    The ML estimate (T&B 1999 eq. C.23 / the closed form eq. 8) is RSS_i / (n_i (d - q)), the residual
    sum of squares outside a q-dimensional subspace fitted to the same n_i rows. Under isotropic noise
    sigma^2, E[RSS_i] = sigma^2 (d - q)(n_i - 1 - q): the mean takes one degree of freedom per residual
    dimension, and the fitted subspace (q (d - q) free parameters, a point of the Grassmannian) absorbs
    q more. The unbiased variance is therefore RSS_i / ((d - q)(n_i - 1 - q)), i.e. the ML one times

        factor_i = n_i / (n_i - 1 - q)

    (about 1.8 for n_i = 90 rows and q = 40; -> 1 for n_i >> q). Args: counts (M,) responsibility sums
    n_i, d features, q latent dimensions. Returns (factor (M,) >= 1, underdetermined (M,) bool): a
    component with n_i <= q + 1 rows has no degrees of freedom left (factor 1, flagged).
    """
    n = np.asarray(counts, dtype=np.float64)
    under = n <= q + 1
    factor = np.ones_like(n)
    factor[~under] = n[~under] / (n[~under] - 1.0 - q)
    return factor, under
