"""Gaussian conditioning of a mixture of PPCA: the posterior of every dimension given the observed ones.

The one conditioning path of silpose: :meth:`ShapeStructureModel.infer` calls it for each pattern
of present views; the tests compare it with dense conditioning (d x d covariances).

Notation. A vector x (d,) splits into an observed block a (d_a dims, indices ``observed``) and a
missing block b. The mixture has weights pi_i (M,), means mu_i (M, d), loadings W_i (M, d, q) and
isotropic noise variances sigma_i^2 (M,) (Tipping & Bishop 1999). The observed values carry extra
zero-mean Gaussian noise of variance s_j^2 >= 0 (one scalar s^2 for all observed dims, or one per
dim). Per component i, with D_i = diag(sigma_i^2 + s_j^2) (d_a,)::

    K_i = I_q + W_a^T D_i^-1 W_a                                          (q, q)
    x_hat_i = K_i^-1 W_a^T D_i^-1 (a - mu_a)                              latent posterior mean (q,)
    log N(a; mu_a, W_a W_a^T + D_i)
        = -1/2 (d_a log 2 pi + log|D_i| + log|K_i| + e^T D_i^-1 e - u^T K_i^-1 u),
          e = a - mu_a,  u = W_a^T D_i^-1 e                                (Woodbury + determinant lemma)
    E[x | a, i] = mu_i + W_i x_hat_i         every dim: at b the conditional mean E[b | a, i], at a the
                                             Bayesian reconstruction mu_a + W_a x_hat_i (the shape model of [8])
    Cov[b | a, i] = W_b K_i^-1 W_b^T + sigma_i^2 I
    r_i = p(i | a) = pi_i N(a; mu_a, C_aa,i) / sum_j pi_j N(a; mu_a, C_aa,j)

The component weights r_i come from each component's marginal likelihood of the observed rows
alone. The mixture posterior mean is ``sum_i r_i E[x | a, i]``; its covariance follows the law of
total covariance, ``sum_i r_i (Cov[b | a, i] + (E[b|a,i] - E[b|a]) (E[b|a,i] - E[b|a])^T)``. With
scalar noise this is docs/conventions.md, "Model": tau^2 = sigma^2 + s^2, M_a = W_a^T W_a + tau^2 I
= tau^2 K, x_hat = M_a^-1 W_a^T (a - mu_a), Cov[b | a, i] = tau^2 W_b M_a^-1 W_b^T + sigma^2 I.
Missing dims are dropped from every product (marginalised), never zero-filled.

Evaluation. All q x q factorisations are done once per (pattern, noise) in :class:`Conditioner`.
A batch then costs two large matrix products per chunk of rows, ``A (N, d_a) @ [P_1 mu_a,1 .. P_M mu_a,M]``
(each component's q + 1 columns side by side, so that one component's are one sub-matrix) with
``P_i = D_i^-1 W_a K_i^-1`` (so ``x_hat_i = a P_i - mu_a P_i``) and ``[r_i x_hat_i]_i @
[W_1^T .. W_M^T]``, with ``e^T D^-1 e`` expanded as ``a^T D^-1 a - 2 a^T D^-1 mu_a + mu_a^T D^-1
mu_a`` from the first product and ``u^T K^-1 u = x_hat^T K x_hat``: O(N (d_a + d) q M) at BLAS-3
speed, no (N, M, d) intermediate. A batch of at least 2 x ``MIN_THREAD_FRAMES`` rows is evaluated in blocks of at
most :data:`THREAD_BLOCK_ROWS` rows on the process's threads, BLAS on one thread each (``silpose.model.threads``): the
element-wise work between the products then runs on every core; each row's values are those of the one-thread
evaluation to rounding (a product's rows blocked differently by BLAS).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .threads import block_bounds, map_blocks

__all__ = ["MixtureParams", "BatchPosterior", "RowsPosterior", "Conditioner", "condition", "condition_rows"]

_LOG_2PI = float(np.log(2.0 * np.pi))
_CHUNK = 2048  # rows per block of the batched products ...
_CHUNK_VALUES = 1 << 21  # ... and fewer when M max(q, d_det) is large: each (M, rows, .) temporary <= 16 MB
#: rows per block when a batch's blocks run on threads (``Conditioner.__call__``, ``Posterior.infer_in_blocks``): each
#: block's temporaries stay small (a process's first large batch maps new memory for each thread's; the benchmark's
#: 2,000 frames: 5,600 page faults in the first call, none after it), and one-thread BLAS is as fast as on the whole
#: batch (the two products, 2,000 rows: 47.0 ms CPU in blocks of 512 or 2,000, 49.8 in 256, 52.0 in 128; load 8)
THREAD_BLOCK_ROWS = 512
#: nats: a component whose log posterior weight is this far below a row's best adds less than e^-30 of that row's
#: means and is left out of their products (Conditioner.__call__)
GATE_NATS = 30.0


@dataclass(frozen=True)
class MixtureParams:
    """The parameters of a mixture of PPCA under the fitted-attribute names of :class:`~silpose.model.mppca.MPPCA`.

    weights_ (M,) pi_i; means_ (M, d) mu_i; components_ (M, d, q) W_i; noise_variance_ (M,) sigma_i^2.
    """

    weights_: np.ndarray
    means_: np.ndarray
    components_: np.ndarray
    noise_variance_: np.ndarray

    @classmethod
    def of(cls, model_or_params) -> "MixtureParams":
        """Validated float64 parameters of a fitted MPPCA (or any object with the four attributes).

        Raises TypeError when an attribute is missing (an unfitted model), ValueError when the shapes
        disagree, a noise variance is <= 0 or a weight < 0.
        """
        try:
            w, mu, W, s2 = (np.asarray(getattr(model_or_params, name), dtype=np.float64)
                            for name in ("weights_", "means_", "components_", "noise_variance_"))
        except AttributeError as exc:
            raise TypeError("condition: the model needs weights_, means_, components_ and noise_variance_ "
                            "(a fitted MPPCA)") from exc
        if W.ndim != 3 or mu.shape != W.shape[:2] or w.shape != (W.shape[0],) or s2.shape != (W.shape[0],):
            raise ValueError(f"condition: inconsistent parameter shapes weights_ {w.shape}, means_ {mu.shape}, "
                             f"components_ {W.shape}, noise_variance_ {s2.shape}")
        if np.any(s2 <= 0) or np.any(w < 0):
            raise ValueError("condition: noise_variance_ must be > 0 and weights_ >= 0")
        return cls(w, mu, W, s2)


@dataclass
class BatchPosterior:
    """Posterior of a batch of N observations (M components, d dims, ``detail`` dims d_det).

    :attr:`mean` (N, d_miss): the mixture posterior mean E[b | a] of the missing dims. With
    ``reconstruct=True``, ``reconstruction`` (N, d) holds E[x | a] for every dim instead (the
    conditional mean at the missing dims, the Bayesian reconstruction at the observed ones) and
    ``missing_mean`` is None; otherwise ``missing_mean`` holds E[b | a] and ``reconstruction`` is None
    (with ``Conditioner(detail_only=True)``: E[detail | a], (N, d_det)).
    best_mean (N, d_det): the most probable component's mean of the detail dims; variance
    (N, d_det): diagonal of the mixture posterior covariance of the detail dims; responsibilities
    (N, M): p(i | a); log_marginal (N,): log p(a) in nats; missing (d_miss,) and detail (d_det,):
    dim indices. Only on request: component_means (N, M, d_det), cov (N, d_det, d_det),
    component_cov (M, d_det, d_det).
    """

    reconstruction: np.ndarray | None
    missing_mean: np.ndarray | None
    best_mean: np.ndarray
    variance: np.ndarray
    responsibilities: np.ndarray
    log_marginal: np.ndarray
    missing: np.ndarray
    detail: np.ndarray
    component_means: np.ndarray | None = None
    cov: np.ndarray | None = None
    component_cov: np.ndarray | None = None

    @property
    def mean(self) -> np.ndarray:
        """(N, d_miss) the conditional mean E[b | a] of the missing dims."""
        return self.missing_mean if self.reconstruction is None else self.reconstruction[:, self.missing]


@dataclass
class RowsPosterior:
    """:func:`condition_rows`: each row conditioned on its own finite entries (N rows, d dims, M components).

    mean, best_mean (N, d) and component_means (N, M, d): the observed values at observed dims and the
    posterior (best component's, each component's) means at missing ones; variance (N, d): posterior
    variance, 0 at observed dims; responsibilities (N, M); log_marginal (N,); missing (N, d) bool.
    """

    mean: np.ndarray
    best_mean: np.ndarray
    component_means: np.ndarray
    variance: np.ndarray
    responsibilities: np.ndarray
    log_marginal: np.ndarray
    missing: np.ndarray


def _observed_index(observed, d: int) -> np.ndarray:
    """(d_a,) indices of the observed dims from a (d,) bool mask or an index array (order kept)."""
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


def _noise(noise_variance, d_a: int) -> np.ndarray:
    """The observation noise as a float64 scalar (0-d) or (d_a,) vector, checked finite and >= 0."""
    noise = np.asarray(noise_variance, dtype=np.float64)
    if noise.ndim != 0 and noise.shape != (d_a,):
        raise ValueError(f"condition: noise_variance must be a scalar or have shape ({d_a},) "
                         f"(one per observed dim), got {noise.shape}")
    if not np.all(np.isfinite(noise)) or np.any(noise < 0):
        raise ValueError("condition: noise_variance must be finite and >= 0")
    return noise


class Conditioner:
    """Precomputed posterior for one observed pattern and one observation noise; call it on batches.

    Args:
        model_or_params: a fitted MPPCA or :class:`MixtureParams` (anything with weights_ (M,),
            means_ (M, d), components_ (M, d, q), noise_variance_ (M,)).
        observed: (d,) bool mask, or (d_a,) integer indices of the observed dims in the column
            order of the observations.
        noise_variance: observation noise s^2 >= 0 on the observed dims (data units squared), a scalar
            or (d_a,) one per observed dim.
        detail: (d_det,) indices of missing dims for which ``best_mean`` and ``variance`` (and on request
            the component means and covariances) are returned; None = every missing dim.
        reconstruct: also reconstruct the observed dims: the posterior mean of all d dims
            (``BatchPosterior.reconstruction``); False = the missing dims only.
        detail_only: the posterior mean of the ``detail`` dims only (``BatchPosterior.missing_mean`` is then
            (N, d_det)); the output product shrinks to O(N d_det q M). Excludes ``reconstruct``.

    Attributes: ``observed`` (d_a,), ``missing`` (d_miss,), ``detail`` (d_det,) indices.
    The q x q factorisations are done here once; a call costs O(N (d_a + d_out) q M), d_out = d
    with ``reconstruct`` else d_miss.
    """

    def __init__(self, model_or_params, observed, noise_variance=0.0, detail=None, reconstruct: bool = False,
                 detail_only: bool = False, output: np.ndarray | None = None):
        p = MixtureParams.of(model_or_params)
        W, mu, sig2 = p.components_, p.means_, p.noise_variance_
        m, d, q = W.shape
        obs = _observed_index(observed, d)
        mask = np.zeros(d, dtype=bool)
        mask[obs] = True
        self.observed, self.missing = obs, np.flatnonzero(~mask)
        det = self.missing if detail is None else np.asarray(detail, dtype=np.intp).reshape(-1)
        if det.size and (det.min() < 0 or det.max() >= d or mask[det].any()):
            raise ValueError("condition: 'detail' must index missing dims")
        self.detail = det
        noise = _noise(noise_variance, obs.size)
        self.m, self.d, self.q, self.d_a = m, d, q, obs.size
        Wa = W[:, obs, :]  # (M, d_a, q)
        mu_a = mu[:, obs]  # (M, d_a)
        if noise.ndim == 0:  # one variance D_i = sigma_i^2 + s^2 for every observed dim
            D = sig2 + float(noise)  # (M,)
            self.invD = 1.0 / D
            self.invD_dims = None
        else:
            D_dims = sig2[:, None] + noise[None, :]  # (M, d_a)
            self.invD_dims = 1.0 / D_dims
            self.invD = None
        # Per component: P_i = D_i^-1 W_a K_i^-1  (d_a, q), so x_hat = (a - mu_a) @ P_i; A holds [P_i mu_a,i] side by
        # side, (d_a, M (q + 1)) (the column block of component i: :meth:`columns`)
        A = np.empty((obs.size, m * (q + 1)))
        self.K = np.empty((m, q, q))
        self.c = np.empty((m, q))  # mu_a @ P_i
        self.log_norm = np.empty(m)  # log pi - 1/2 (d_a log 2 pi + log|D| + log|K|)
        for i in range(m):
            if self.invD_dims is None:
                K = np.eye(q) + (Wa[i].T @ Wa[i]) * self.invD[i]
            else:
                K = np.eye(q) + Wa[i].T @ (Wa[i] * self.invD_dims[i][:, None])
            L = np.linalg.cholesky(K)
            Kinv = np.linalg.inv(K)
            Kinv = 0.5 * (Kinv + Kinv.T)
            if self.invD_dims is None:
                P = Wa[i] @ Kinv * self.invD[i]
            else:
                P = (Wa[i] * self.invD_dims[i][:, None]) @ Kinv
            A[:, i * (q + 1) : i * (q + 1) + q] = P
            self.K[i] = K
            self.c[i] = mu_a[i] @ P
            with np.errstate(divide="ignore"):
                lw = np.log(p.weights_[i])
            if self.invD_dims is None:  # d_a log 2 pi + log|D_i|
                gauss_norm = obs.size * (_LOG_2PI + np.log(D[i]))
            else:
                gauss_norm = obs.size * _LOG_2PI + np.log(D_dims[i]).sum()
            self.log_norm[i] = lw - 0.5 * (gauss_norm + 2.0 * np.log(np.diag(L)).sum())
        if self.invD_dims is None:  # a^T mu_a (times D^-1 later) and ||mu_a||^2
            A[:, q :: q + 1] = mu_a.T
            self.mu_sq = np.einsum("ij,ij->i", mu_a, mu_a)
        else:  # a^T D^-1 mu_a and mu_a^T D^-1 mu_a
            A[:, q :: q + 1] = (mu_a * self.invD_dims).T
            self.mu_sq = np.einsum("ij,ij->i", mu_a * self.invD_dims, mu_a)
        self.A = A
        # the dims whose mixture mean is returned, and where the detail dims sit among them
        self.reconstruct = bool(reconstruct)
        if self.reconstruct and detail_only:
            raise ValueError("condition: reconstruct and detail_only exclude each other")
        if detail_only:
            out_dims = det
            self.detail_pos = np.arange(det.size)
        else:
            out_dims = np.arange(d) if self.reconstruct else self.missing
            self.detail_pos = det if self.reconstruct else np.searchsorted(self.missing, det)
        # stacked W_i^T (Mq, d_out), then the means (M, d_out): [r_i x_hat_i, r_i] @ B is the mixture mean
        self.shared_output = output is not None and self.reconstruct
        if self.shared_output:  # the same for every pattern and noise: one copy per mixture (output_matrix)
            if output.shape != (m * q + m, d):
                raise ValueError(f"condition: output must have shape ({m * q + m}, {d}), got {output.shape}")
            self.B = output
        else:
            self.B = self.output_matrix(p, out_dims)
        self.W_det = W[:, det, :]  # (M, d_det, q)
        self.WdT = np.ascontiguousarray(self.W_det.transpose(0, 2, 1))  # (M, q, d_det): BLAS-ready right-hand sides
        self.mu_det = mu[:, det]
        # the detail dims among the returned ones as a slice when consecutive (the joints block: a view, not a copy)
        pos = np.asarray(self.detail_pos)
        run = pos.size > 0 and bool((np.diff(pos) == 1).all())
        self.detail_cols = slice(int(pos[0]), int(pos[-1]) + 1) if run else pos
        self.Kinv = np.linalg.inv(self.K)
        self.sig2 = sig2
        # posterior variance of the detail dims per component: diag(W_det K^-1 W_det^T) + sigma^2
        self.var_det = np.einsum("mjq,mqr,mjr->mj", self.W_det, self.Kinv, self.W_det) + sig2[:, None]  # (M, d_det)

    @staticmethod
    def output_matrix(model_or_params, out_dims=None) -> np.ndarray:
        """(M q + M, d_out) the stacked W_i^T then the means at ``out_dims`` (None = every dim): the output
        product's right-hand side, which a ``reconstruct`` conditioner can share (its ``output`` argument)."""
        p = MixtureParams.of(model_or_params)
        m, d, q = p.components_.shape
        out = np.arange(d) if out_dims is None else np.asarray(out_dims, dtype=np.intp)
        Wo = p.components_ if out_dims is None else p.components_[:, out, :]
        return np.concatenate([Wo.transpose(0, 2, 1).reshape(m * q, out.size),
                               p.means_ if out_dims is None else p.means_[:, out]])

    def columns(self, components) -> np.ndarray:
        """Columns of :attr:`A` of ``components`` (k,) indices: each one's q columns of P_i, then its mu_a,i column
        ((k (q + 1),), in the order given)."""
        idx = np.asarray(components, dtype=np.intp).reshape(-1)
        return (idx[:, None] * (self.q + 1) + np.arange(self.q + 1)[None, :]).reshape(-1)

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays this conditioner holds (what a cache of them keeps alive; the means may be a
        view of the mixture's; a shared output matrix is not counted)."""
        return int(sum(v.nbytes for k, v in vars(self).items()
                       if isinstance(v, np.ndarray) and not (k == "B" and self.shared_output)))

    def component_cov(self) -> np.ndarray:
        """(M, d_det, d_det) per-component posterior covariance of the detail dims,
        ``W_det K^-1 W_det^T + sigma_i^2 I`` (independent of the observed values)."""
        return (np.matmul(np.matmul(self.W_det, self.Kinv), self.W_det.transpose(0, 2, 1))
                + self.sig2[:, None, None] * np.eye(self.detail.size))

    def checked_rows(self, X_obs) -> np.ndarray:
        """X_obs (N, d_a) (or (d_a,) for one row) as a float64 2-D array; ValueError for a wrong shape, NaN or inf."""
        X = np.asarray(X_obs, dtype=np.float64)
        if X.ndim == 1:
            X = X[None, :]
        if X.ndim != 2 or X.shape[1] != self.d_a:
            raise ValueError(f"condition: X_obs must have shape (N, {self.d_a}) (one column per observed "
                             f"dim), got {np.shape(X_obs)}")
        if not np.all(np.isfinite(X)):
            raise ValueError("condition: X_obs contains NaN or inf; use condition_rows for per-row missing dims")
        return X

    def __call__(self, X_obs, *, return_components: bool = False, return_cov: bool = False,
                 components=None, out: np.ndarray | None = None) -> BatchPosterior:
        """Posterior for observations X_obs (N, d_a) (or (d_a,) for one row), columns in ``observed`` order.

        ``return_components`` adds the component means of the detail dims (N, M, d_det); ``return_cov``
        the mixture and per-component covariances of the detail dims (module doc). ``components``: indices of
        the only components to evaluate (the others get responsibility 0 and NaN component means; the caller
        knows they are negligible, e.g. more than :data:`GATE_NATS` below the best); None = all. Components whose
        log posterior weight is more than :data:`GATE_NATS` below a row's best add nothing to the means: they are
        left out of the output product where no row of a block needs them (relative change < M e^-30).
        ``out``: an (N, d_out) float64 array (e.g. rows of a larger one) the mixture mean is written to and returned
        in (``reconstruction`` or ``missing_mean``); None = a new one.
        Raises ValueError for a wrong shape, NaN or inf, or values so large that the log density overflows.
        """
        X = np.asarray(X_obs, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != self.d_a:
            X = self.checked_rows(X_obs)  # a shape error, or one row (d_a,); NaN and inf are caught per chunk below
        m_all, q, n_det = self.m, self.q, self.detail.size
        if return_cov and components is not None:
            raise ValueError("condition: return_cov needs every component (components=None)")
        sub = _Subset(self, components)
        m = sub.m
        n = X.shape[0]
        if out is None:
            mean = np.empty((n, self.B.shape[1]))
        elif out.shape != (n, self.B.shape[1]) or out.dtype != np.float64:
            raise ValueError(f"condition: out must be a float64 array of shape ({n}, {self.B.shape[1]}), got "
                             f"{out.dtype} {out.shape}")
        else:
            mean = out
        best = np.empty((n, n_det))
        var = np.empty((n, n_det))
        resp = np.zeros((n, m_all)) if sub.idx is not None else np.empty((n, m_all))
        logm = np.empty(n)
        want_cm = return_components or return_cov
        cmeans = None
        if want_cm:
            cmeans = np.empty((n, m_all, n_det)) if sub.idx is None else np.full((n, m_all, n_det), np.nan)
        chunk = int(min(_CHUNK, max(64, _CHUNK_VALUES // max(1, m * max(q, n_det)))))

        def rows(bounds: tuple[int, int]) -> None:  # one block of rows: every output row of it written here
            sl = slice(*bounds)
            x = X[sl]
            b = x.shape[0]
            Pm = (x @ sub.A).reshape(b, m, q + 1)  # a @ P_i and a . mu_a,i (D^-1-weighted) for every i
            # x_hat (M, b, q), contiguous per component for the batched products below
            xh = np.ascontiguousarray(Pm[:, :, :q].transpose(1, 0, 2)) - sub.c[:, None, :]
            if self.invD_dims is None:
                xx = np.einsum("ij,ij->i", x, x)
                e2 = xx[:, None] - 2.0 * Pm[:, :, q] + sub.mu_sq[None, :]  # ||a - mu_a,i||^2  (b, M)
                maha = e2 * sub.invD[None, :]
            else:
                maha = (x * x) @ sub.invD_dims.T - 2.0 * Pm[:, :, q] + sub.mu_sq[None, :]  # e^T D^-1 e
            if not np.isfinite(maha).all():  # NaN or inf in x (the error), or squares that overflow (caught below)
                self.checked_rows(x)
            quad = np.sum(np.matmul(xh, sub.K) * xh, axis=2).T  # u^T K^-1 u = x_hat^T K x_hat  (b, M)
            logp = sub.log_norm[None, :] - 0.5 * (maha - quad)
            top = logp.max(axis=1, keepdims=True)  # log-sum-exp, stable
            r = np.exp(logp - top)
            tot = r.sum(axis=1, keepdims=True)
            r /= tot
            lm = (top + np.log(tot))[:, 0]
            act = np.flatnonzero(((logp - top) > -GATE_NATS).any(axis=0))  # components any row needs
            if act.size == m:
                act = slice(None)
            ra, xa = r[:, act], xh[act]
            k = ra.shape[1]
            G = np.empty((b, k * q + k))  # [r_i x_hat_i, r_i]
            G[:, : k * q] = (xa * ra.T[:, :, None]).transpose(1, 0, 2).reshape(b, k * q)
            G[:, k * q :] = ra
            np.matmul(G, sub.B if isinstance(act, slice) else sub.B[sub.rows(act)], out=mean[sl])
            # per-component means of the detail dims (M, b, d_det): those of the components in use
            cm = sub.mu_det[act, None, :] + np.matmul(xa, sub.WdT[act])
            best[sl] = cm[np.argmax(ra, axis=1), np.arange(b)]
            dev = cm - mean[sl, self.detail_cols][None]
            var[sl] = ra @ sub.var_det[act] + np.einsum("bm,mbj->bj", ra, dev * dev)  # law of total variance
            sub.scatter(resp, sl, r)
            logm[sl] = lm
            if want_cm:
                if not isinstance(act, slice):  # every component's mean was asked for
                    cm = sub.mu_det[:, None, :] + np.matmul(xh, sub.WdT)
                sub.scatter(cmeans, sl, cm.transpose(1, 0, 2))

        # blocks of at most `chunk` rows; a large batch's on threads, each block's products on one BLAS thread
        # (silpose.model.threads.map_blocks): the element-wise work between the products runs on both cores then
        if n:
            blocks, threads = block_bounds(n, chunk)
            if threads > 1:  # blocks of a thread's cache size (module doc, "Evaluation")
                blocks, threads = block_bounds(n, min(chunk, THREAD_BLOCK_ROWS))
            map_blocks(rows, blocks, threads)
        if not np.all(np.isfinite(logm)):
            row = int(np.flatnonzero(~np.isfinite(logm))[0])
            raise ValueError(f"condition: the log density of row {row} is not finite (X_obs values too large)")
        out = BatchPosterior(mean if self.reconstruct else None, None if self.reconstruct else mean, best, var, resp,
                        logm, self.missing, self.detail)
        if return_components:
            out.component_means = cmeans
        if return_cov:
            out.component_cov = self.component_cov()
            dev = cmeans - mean[:, self.detail_pos][:, None, :]  # (N, M, d_det)
            out.cov = (np.einsum("nm,mij->nij", resp, out.component_cov)
                       + np.einsum("nm,nmi,nmj->nij", resp, dev, dev))
        return out


class _Subset:
    """The per-component arrays of a :class:`Conditioner` restricted to ``components`` (None = all of them)."""

    def __init__(self, cond: "Conditioner", components) -> None:
        m, q = cond.m, cond.q
        self.q = q
        self.WdT = cond.WdT  # (M, q, d_det)
        names = ("c", "mu_sq", "log_norm", "K", "mu_det", "var_det")
        if components is None:
            self.idx, self.m, self.A, self.B = None, m, cond.A, cond.B
            self.invD, self.invD_dims = cond.invD, cond.invD_dims
            for name in names:
                setattr(self, name, getattr(cond, name))
            return
        idx = np.asarray(components, dtype=np.intp).reshape(-1)
        if idx.size == 0 or idx.min() < 0 or idx.max() >= m or np.unique(idx).size != idx.size:
            raise ValueError(f"condition: components must be distinct indices in [0, {m}), got {idx}")
        self.idx, self.m = idx, idx.size
        self.A = np.ascontiguousarray(cond.A[:, cond.columns(idx)])
        self.B = cond.B[np.concatenate([(idx[:, None] * q + np.arange(q)[None, :]).reshape(-1), m * q + idx])]
        self.invD = None if cond.invD is None else cond.invD[idx]
        self.invD_dims = None if cond.invD_dims is None else cond.invD_dims[idx]
        self.WdT = self.WdT[idx]
        for name in names:
            setattr(self, name, getattr(cond, name)[idx])

    def rows(self, act: np.ndarray) -> np.ndarray:
        """Rows of this subset's B for its components ``act``: their W^T blocks, then their means."""
        return np.concatenate([(act[:, None] * self.q + np.arange(self.q)[None, :]).reshape(-1), self.m * self.q + act])

    def scatter(self, out: np.ndarray, sl: slice, values: np.ndarray) -> None:
        """``out[sl]`` = ``values`` (b, M_subset, ...) at this subset's components."""
        if self.idx is None:
            out[sl] = values
        else:
            out[sl, self.idx] = values



def condition(model_or_params, X_obs, observed, noise_variance=0.0, *, detail=None, reconstruct: bool = False,
              return_components: bool = False, return_cov: bool = False) -> BatchPosterior:
    """Posterior of a mixture of PPCA given observations of some dims: ``Conditioner(...)(X_obs, ...)``.

    model_or_params: fitted MPPCA or :class:`MixtureParams`. X_obs (N, d_a): observed values, columns
    in the order of ``observed``, a (d,) bool mask or (d_a,) index array. noise_variance: scalar or
    (d_a,) observation-noise variance added to the model noise of the observed dims. Returns
    a :class:`BatchPosterior` (module doc for the equations).
    """
    return Conditioner(model_or_params, observed, noise_variance, detail, reconstruct)(
        X_obs, return_components=return_components, return_cov=return_cov)


def condition_rows(model_or_params, X, noise_variance=0.0) -> RowsPosterior:
    """Condition each row on its own finite entries; NaN marks a missing dim.

    X (N, d) with NaN where a dim is missing (rows may miss different dims: rows are grouped by
    pattern and each group is conditioned once by a :class:`Conditioner`). noise_variance: scalar or
    (d,) per dim (only each row's observed entries are used). Returns a :class:`RowsPosterior`.
    """
    p = MixtureParams.of(model_or_params)
    m, d, _ = p.components_.shape
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
    for g, pattern in enumerate(patterns):
        rows = np.flatnonzero(group == g)
        obs = np.flatnonzero(~pattern)
        res = Conditioner(p, obs, noise if noise.ndim == 0 else noise[obs])(X[np.ix_(rows, obs)],
                                                                             return_components=True)
        mcols = res.missing
        mean[np.ix_(rows, mcols)] = res.mean
        best[np.ix_(rows, mcols)] = res.best_mean
        cmeans[rows[:, None, None], np.arange(m)[None, :, None], mcols[None, None, :]] = res.component_means
        variance[np.ix_(rows, mcols)] = res.variance
        resp[rows] = res.responsibilities
        log_marg[rows] = res.log_marginal
    return RowsPosterior(mean=mean, best_mean=best, component_means=cmeans, variance=variance,
                         responsibilities=resp, log_marginal=log_marg, missing=miss)
