"""A first pass in float32 over every component: which few each frame's exact posterior needs.

A Gaussian pass must weigh every mixture component, and the observed-block product that does it,
``a (d_a,) @ [P_1 .. P_M]`` per frame (:mod:`silpose.model.conditioning`), reads a (d_a, M q) matrix: 105 MB
for M 200, q 40 and 4 views, memory-bound for a single frame. Robust inference (``silpose.model.robust``)
also makes two Gaussian passes of the same input, at the model's noise and at the frame's adaptive noise.

:class:`Screen` computes, once per input, the noise-independent projections ``z_i = W_a,i^T a`` (q,) in
float32 for every component (half the bytes of the float64 product), and ``mu_a,i^T a``, ``||a||^2`` exactly
in float64 (M columns only). For any scalar noise level (a :class:`~silpose.model.conditioning.Conditioner`
with K_i, D_i = sigma_i^2 + s^2) they give every component's approximate log density::

    u_i = z_i - W_a,i^T mu_a,i,   x_hat_i = K_i^-1 u_i / D_i,
    log p_i = log pi_i - 1/2 (d_a log 2 pi + log|D_i| + log|K_i|
                              + (||a||^2 - 2 mu_a,i^T a + ||mu_a,i||^2) / D_i - x_hat_i^T K_i x_hat_i)

(the conditioning module's equations with ``u = W_a^T D^-1 e``). The float32 rounding enters only through
``x_hat``: its error in ``log p`` was below 0.05 nats on the default and motions-size models, and
:data:`SCREEN_MARGIN` nats are added to the gate. The components within ``GATE_NATS + SCREEN_MARGIN`` of a
frame's best are then conditioned exactly, in float64 (:func:`~silpose.model.gated.condition_gated`); the others
are more than GATE_NATS below the best and count as 0 (relative change of the means < M e^-30), as in the gated
output product of ``Conditioner.__call__``.
"""

from __future__ import annotations

import numpy as np

from .conditioning import GATE_NATS, Conditioner

__all__ = ["SCREEN_MARGIN", "ScreenMatrices", "Screen"]

#: nats added to GATE_NATS when choosing components from the float32 screen (module doc)
SCREEN_MARGIN = 10.0


class ScreenMatrices:
    """The noise-independent matrices of one observed pattern: ``S`` (d_a, M q) float32 stacked W_a,i, ``mu_a``
    (d_a, M) float64, ``w_mu`` (M, q) = W_a,i^T mu_a,i. ``observed`` (d_a,) dims of the mixture's ``components_``
    (M, d, q) and ``means_`` (M, d)."""

    def __init__(self, components: np.ndarray, means: np.ndarray, observed: np.ndarray) -> None:
        W = np.asarray(components)[:, observed, :]  # (M, d_a, q)
        m, d_a, q = W.shape
        self.m, self.q = m, q
        self.S = np.ascontiguousarray(W.transpose(1, 0, 2).reshape(d_a, m * q), dtype=np.float32)
        mu_a = np.asarray(means, dtype=np.float64)[:, observed]
        self.mu_a = np.ascontiguousarray(mu_a.T)
        self.w_mu = np.einsum("mdq,md->mq", W, mu_a)

    @property
    def nbytes(self) -> int:
        return int(self.S.nbytes + self.mu_a.nbytes + self.w_mu.nbytes)


class Screen:
    """The screening projections of rows X (N, d_a) (module doc) under one pattern's :class:`ScreenMatrices`."""

    def __init__(self, mats: ScreenMatrices, X: np.ndarray) -> None:
        X = np.asarray(X, dtype=np.float64)
        self.mats = mats
        self.z = (X.astype(np.float32) @ mats.S).reshape(len(X), mats.m, mats.q)  # (N, M, q) float32
        self.xm = X @ mats.mu_a  # (N, M)
        self.xx = np.einsum("ij,ij->i", X, X)

    def candidates(self, cond: Conditioner, rows=None) -> np.ndarray:
        """(n, M) bool: the components within GATE_NATS + SCREEN_MARGIN of each row's best under ``cond`` (a
        scalar-noise conditioner of this pattern); ``rows`` (n,) indices into X, None = all."""
        if cond.invD is None:
            raise ValueError("the screen needs a scalar observation noise")
        sl = slice(None) if rows is None else rows
        u = self.z[sl] - self.mats.w_mu  # (n, M, q) float64
        ut = u.transpose(1, 0, 2)  # (M, n, q)
        xk = np.matmul(ut, cond.Kinv)  # K^-1 u per component
        quad = np.einsum("mnq,mnq->nm", xk, ut) * (cond.invD ** 2)[None, :]  # x_hat^T K x_hat = u^T K^-1 u / D^2
        maha = (self.xx[sl][:, None] - 2.0 * self.xm[sl] + cond.mu_sq[None, :]) * cond.invD[None, :]
        logp = cond.log_norm[None, :] - 0.5 * (maha - quad)
        return logp >= logp.max(axis=1, keepdims=True) - (GATE_NATS + SCREEN_MARGIN)
