"""Fused posterior of a PPCA mixture for one observed pattern: the fast path of ``ShapeStructureModel.infer``.

Same equations as :mod:`silpose.model.conditional` (DESIGN §4, Tipping & Bishop 1999), for the
case inference needs: scalar observation noise s^2 on the observed dims a, and the posterior of the
*whole* vector (missing dims b, and the Bayesian reconstruction of the observed dims). Per component
i, with ``D_i = sigma_i^2 + s^2`` and ``K_i = I_q + W_a^T W_a / D_i`` (q x q)::

    x_hat_i = K_i^-1 W_a^T (a - mu_a) / D_i                     latent posterior mean
    log N(a; mu_a, C_aa) = -1/2 (d_a log 2 pi + d_a log D_i + log|K_i| + ||e||^2 / D_i - u^T K_i^-1 u),
                           e = a - mu_a, u = W_a^T e / D_i       (Woodbury + determinant lemma)
    E[x | a, i] = mu_i + W_i x_hat_i                            all d dims: b (the conditional mean)
                                                                and a (reconstruction, as in [8])
    Var[x_b | a, i] = diag(W_b K_i^-1 W_b^T) + sigma_i^2

Mixture: r_i = p(i | a) (softmax of the log terms plus log pi_i), mean = sum_i r_i E[x | a, i], and
the law of total variance for the reported dims. Evaluation is arranged as two large matrix
products per chunk — ``A (N, d_a) @ [W_a K^-1 / D]_i`` and ``[r_i x_hat_i] @ [W_i^T]_i`` — with
``||e||^2 = ||a||^2 - 2 a.mu_a + ||mu_a||^2`` from the same first product, so the cost is
O(N (d_a + d) q M) with BLAS-3 efficiency and no (N, M, d) intermediate.
"""

from __future__ import annotations

import numpy as np

_LOG_2PI = float(np.log(2.0 * np.pi))
_CHUNK = 2048


class PatternPosterior:
    """Precomputed posterior for one observed-dimension pattern and one noise variance.

    Args:
        weights: (M,) mixing proportions; means: (M, d); components: (M, d, q); noise_variance: (M,) sigma_i^2.
        observed: (d,) bool, the observed dims.
        s2: observation-noise variance >= 0 on the observed dims.
        detail: (d_det,) int indices of dims for which the best-component mean and the posterior variance
            are returned (the structure block; they should be missing dims).
    """

    def __init__(self, weights, means, components, noise_variance, observed, s2: float, detail):
        w = np.asarray(weights, dtype=np.float64)
        mu = np.asarray(means, dtype=np.float64)
        W = np.asarray(components, dtype=np.float64)
        sig2 = np.asarray(noise_variance, dtype=np.float64)
        m, d, q = W.shape
        obs = np.flatnonzero(np.asarray(observed, dtype=bool))
        det = np.asarray(detail, dtype=np.intp)
        self.m, self.d, self.q, self.d_a = m, d, q, obs.size
        self.obs = obs
        D = sig2 + float(s2)  # (M,)
        self.invD = 1.0 / D
        Wa = W[:, obs, :]  # (M, d_a, q)
        mu_a = mu[:, obs]  # (M, d_a)
        # Per component: P_i = W_a K^-1 / D  (d_a, q), so x_hat = (a - mu_a) @ P_i.
        A = np.empty((obs.size, m * q + m))
        self.K = np.empty((m, q, q))
        self.c = np.empty((m, q))  # mu_a @ P_i
        self.mu_sq = np.einsum("ij,ij->i", mu_a, mu_a)
        self.log_norm = np.empty(m)  # log pi - 1/2 (d_a log 2 pi + d_a log D + log|K|)
        for i in range(m):
            K = np.eye(q) + (Wa[i].T @ Wa[i]) * self.invD[i]
            L = np.linalg.cholesky(K)
            Kinv = np.linalg.inv(K)
            Kinv = 0.5 * (Kinv + Kinv.T)
            P = Wa[i] @ Kinv * self.invD[i]
            A[:, i * q : (i + 1) * q] = P
            self.K[i] = K
            self.c[i] = mu_a[i] @ P
            with np.errstate(divide="ignore"):
                lw = np.log(w[i])
            self.log_norm[i] = lw - 0.5 * (obs.size * (_LOG_2PI + np.log(D[i])) + 2.0 * np.log(np.diag(L)).sum())
        A[:, m * q :] = mu_a.T
        self.A = A
        self.B = np.ascontiguousarray(W.transpose(0, 2, 1).reshape(m * q, d))  # stacked W_i^T (Mq, d)
        self.means = mu
        self.det = det
        Wd = W[:, det, :]  # (M, d_det, q)
        self.W_det = Wd
        self.mu_det = mu[:, det]
        Kinv_all = np.linalg.inv(self.K)  # posterior variance of the detail dims: diag(W K^-1 W^T) + sigma^2
        self.var_det = np.einsum("mjq,mqr,mjr->mj", Wd, Kinv_all, Wd) + sig2[:, None]  # (M, d_det)

    def __call__(self, X_obs: np.ndarray):
        """Posterior for observations X_obs (N, d_a).

        Returns:
            mean (N, d) mixture posterior mean of every dim; best_det (N, d_det) best component's mean of the
            detail dims; var_det (N, d_det) mixture posterior variance of the detail dims; resp (N, M);
            log_marginal (N,).
        """
        X = np.asarray(X_obs, dtype=np.float64)
        n, m, q = X.shape[0], self.m, self.q
        mean = np.empty((n, self.d))
        best = np.empty((n, self.det.size))
        var = np.empty((n, self.det.size))
        resp = np.empty((n, m))
        logm = np.empty(n)
        Kt = self.K  # (M, q, q)
        WdT = self.W_det.transpose(0, 2, 1)  # (M, q, d_det)
        for s in range(0, n, _CHUNK):
            sl = slice(s, min(s + _CHUNK, n))
            x = X[sl]
            b = x.shape[0]
            Pm = x @ self.A  # (b, Mq + M): a @ P_i for every i, then a . mu_a,i
            xx = np.einsum("ij,ij->i", x, x)
            xh = Pm[:, : m * q].reshape(b, m, q).transpose(1, 0, 2) - self.c[:, None, :]  # x_hat (M, b, q)
            e2 = xx[:, None] - 2.0 * Pm[:, m * q :] + self.mu_sq[None, :]  # ||a - mu_a,i||^2  (b, M)
            quad = np.sum(np.matmul(xh, Kt) * xh, axis=2).T  # u^T K^-1 u = x_hat^T K x_hat  (b, M)
            logp = self.log_norm[None, :] - 0.5 * (e2 * self.invD[None, :] - quad)
            top = logp.max(axis=1, keepdims=True)  # log-sum-exp, stable
            r = np.exp(logp - top)
            tot = r.sum(axis=1, keepdims=True)
            r /= tot
            lm = (top + np.log(tot))[:, 0]
            H = (xh * r.T[:, :, None]).transpose(1, 0, 2).reshape(b, m * q)  # [r_i x_hat_i]
            mean[sl] = H @ self.B + r @ self.means
            cm = self.mu_det[:, None, :] + np.matmul(xh, WdT)  # per-component means of the detail dims (M, b, d_det)
            best[sl] = cm[np.argmax(r, axis=1), np.arange(b)]
            dev = cm - mean[sl][:, self.det][None]
            var[sl] = r @ self.var_det + np.einsum("bm,mbj->bj", r, dev * dev)  # law of total variance
            resp[sl] = r
            logm[sl] = lm
        return mean, best, var, resp, logm
