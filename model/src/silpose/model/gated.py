"""Conditioning with a set of components per frame: each component's frames in one product.

A reweighting pass of robust inference (``silpose.model.robust``) knows from the pass before which few mixture
components matter for each frame: those whose posterior weight was within :data:`~silpose.model.conditioning.GATE_NATS`
of the frame's best. :func:`condition_gated` evaluates exactly those (frame, component) pairs and treats every other
component of a frame as negligible (responsibility 0), with the equations of :mod:`silpose.model.conditioning`
(its module doc), restricted per frame n to its set S_n::

    x_hat_ni = a_n P_i - mu_a,i P_i                         (q,), i in S_n,  P_i = D_i^-1 W_a,i K_i^-1
    log p_ni = log pi_i - 1/2 (d_a log 2 pi + log|D_i| + log|K_i| + e^T D_i^-1 e - x_hat^T K_i x_hat)
    r_ni = p_ni / sum_{j in S_n} p_nj,                     log p(a_n) = log sum_{j in S_n} p_nj
    E[x | a_n] = sum_{i in S_n} r_ni (mu_i + W_i x_hat_ni)

The frames of component i are gathered and multiplied at once, ``A_n_i (n_i, d_a) @ [P_i | mu_a,i]`` and
``[r x_hat, r] (n_i, q + 1) @ [W_i^T; mu_i]``: O(sum_n |S_n| (d_a + d) q) in one BLAS-3 product per component
instead of O(N M (d_a + d) q) for every frame and component (a frame has one or two components within the gate
where the mixture's components are well apart, against M of 5 to 200). Pairs more than ``GATE_NATS`` below their
frame's best in this pass are left out of the means, as in ``Conditioner.__call__``.
"""

from __future__ import annotations

import numpy as np

from .conditioning import GATE_NATS, BatchPosterior, Conditioner

__all__ = ["condition_gated", "rows_where"]


def condition_gated(cond: Conditioner, X_obs: np.ndarray, mask: np.ndarray) -> BatchPosterior:
    """Posterior of observations X_obs (N, d_a) given only the components ``mask`` (N, M) bool of each row (module
    doc): ``cond(X_obs, components=...)`` with one subset per row. Responsibilities are 0 outside a row's set; no
    component means or covariances. Raises ValueError for a wrong shape, a row without components, NaN or inf.

    Each component's rows are read as one slice where they are consecutive (no gathered copy), its ``a P_i`` and
    ``a . mu_a,i`` come from one product with its q + 1 columns of ``cond.A``, and when every row has one component
    in its set, a row gets ``mu_i + x_hat_i W_i^T`` written directly (its responsibility is exactly 1: the same values
    as the sum over the set)."""
    X = np.asarray(X_obs, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != cond.d_a:
        X = cond.checked_rows(X_obs)
    m, q, n = cond.m, cond.q, X.shape[0]
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != (n, m):
        raise ValueError(f"condition: the per-row component mask must have shape ({n}, {m}), got {mask.shape}")
    count = mask.sum(axis=1)
    if n and not (count > 0).all():
        raise ValueError("condition: every row needs at least one component in its mask")
    A, B = cond.A, cond.B
    xx = np.einsum("ij,ij->i", X, X)  # ||a||^2; not finite: NaN or inf in X (or squares that overflow)
    if not np.isfinite(xx).all():
        cond.checked_rows(X)
    logp = np.full((n, m), -np.inf)
    used = np.flatnonzero(mask.any(axis=0))
    rows_of, xh_of = [], []
    for i in used:  # the observed block: x_hat and log p of this component's rows
        rows = rows_where(mask[:, i])
        x = X[rows]
        y = x @ A[:, i * (q + 1):(i + 1) * (q + 1)]  # [a P_i, a . mu_a,i]
        xh = y[:, :q] - cond.c[i]
        xm = y[:, q]
        if cond.invD_dims is None:
            maha = (xx[rows] - 2.0 * xm + cond.mu_sq[i]) * cond.invD[i]
        else:
            maha = (x * x) @ cond.invD_dims[i] - 2.0 * xm + cond.mu_sq[i]
        quad = np.einsum("bq,bq->b", xh @ cond.K[i], xh)
        logp[rows, i] = cond.log_norm[i] - 0.5 * (maha - quad)
        rows_of.append(rows)
        xh_of.append(xh)
    top = logp.max(axis=1, keepdims=True)
    rel = logp - top
    r = np.exp(rel)
    tot = r.sum(axis=1, keepdims=True)
    r /= tot
    logm = (top + np.log(tot))[:, 0]
    if not np.all(np.isfinite(logm)):
        row = int(np.flatnonzero(~np.isfinite(logm))[0])
        raise ValueError(f"condition: the log density of row {row} is not finite (X_obs values too large)")
    keep = rel > -GATE_NATS  # the pairs that enter the means
    # the output: sum_i r_i mu_i for the components in use, then each component's r_i x_hat_i W_i^T on its rows; when
    # every row has one component: mu_i + x_hat_i W_i^T at once (r_i = 1 exactly, the other terms 0)
    single = bool((count == 1).all())
    mean = np.empty((n, B.shape[1])) if single else r[:, used] @ B[m * q + used]
    pairs = []
    for i, rows, xh in zip(used, rows_of, xh_of):
        k = keep[rows, i]
        if not k.any():
            continue
        rr, xk = (rows, xh) if k.all() else (np.arange(n)[rows][k], xh[k])
        ri = r[rr, i]
        if single and isinstance(rr, slice):
            np.matmul(xk, B[i * q:(i + 1) * q], out=mean[rr])
            mean[rr] += B[m * q + i]
        elif single:
            out = xk @ B[i * q:(i + 1) * q]
            out += B[m * q + i]
            mean[rr] = out
        else:
            mean[rr] += (xk * ri[:, None]) @ B[i * q:(i + 1) * q]
        pairs.append((i, rr, xk, ri))
    # detail dims: the best component's mean and the law of total variance over the pairs in use
    mdet = mean[:, cond.detail_pos]
    var = r[:, used] @ cond.var_det[used]
    best = np.empty((n, cond.detail.size))
    best_i = np.argmax(r, axis=1)
    for i, rr, xk, ri in pairs:
        cm = xk @ cond.W_det[i].T
        cm += cond.mu_det[i]
        dev = cm - mdet[rr]
        var[rr] += ri[:, None] * dev * dev
        sel = best_i[rr] == i
        if isinstance(rr, slice):
            best[rr][sel] = cm[sel]  # best[rr] is a view
        else:
            best[rr[sel]] = cm[sel]
    return BatchPosterior(mean if cond.reconstruct else None, None if cond.reconstruct else mean, best, var, r,
                          logm, cond.missing, cond.detail)


def rows_where(flags: np.ndarray) -> slice | np.ndarray:
    """The rows where ``flags`` (N,) is True: a slice when they are consecutive (their rows are then read as views,
    not gathered copies), else their indices."""
    rows = np.flatnonzero(flags)
    if rows.size and rows[-1] - rows[0] + 1 == rows.size:
        return slice(int(rows[0]), int(rows[-1]) + 1)
    return rows
