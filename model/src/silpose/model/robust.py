"""Robust inference: heavy-tailed per-point noise by iteratively reweighted conditioning.

The Gaussian observation model of ``silpose.model.conditioning`` charges a contour point's
residual quadratically, so a hole, a blob or a shadow in the mask (tens of pixels) can outweigh
the rest of the silhouette. Here each contour point p of each present view gets a weight
``u_p`` in [0, 1] -- its observation noise becomes ``D / u_p`` -- from Tukey's biweight of its
residual against the current reconstruction::

    r_p = || a_p - rec_p ||                          (px; a_p observed, rec_p reconstructed point)
    s   = 1.4826 median_p(r_p) + floor               (robust scale of the view, px)
    u_p = (1 - (r_p / (c s))^2)^2  if r_p < c s, else 0        (c = ``threshold``, 3 by default)

Conditioning with per-point variances ``D / u_p`` costs O(d q^2) per frame and component. We use
its EM form instead (the *pseudo-observation* iteration): the observation is replaced by
``a~ = rec + u (a - rec)`` and conditioned with the unweighted, precomputed posterior. For a fixed
component its fixed point x* solves ``(I + W^T U W / D) x* = W^T U (a - mu) / D`` -- exactly the
weighted conditioning -- and each iteration costs one ordinary batched inference, O(d q M) per
frame. Points with weight 0 are imputed by the model (treated as missing). The pseudo-observation
is re-normalised at every iteration, so outliers stop shifting the view's centroid and scale, and
the component weights are recomputed, so the winning component can change.

``window`` > 0 also re-estimates correspondences: point p is compared with the nearest observed
point among indices p - window .. p + window (an arc-length shift from a blob or shadow elsewhere
on the contour otherwise makes every later point an outlier).

Measured on the default preset (300 test walkers, 4 views, 8 iterations; pose error cm / mean
Chamfer px of the 4 reconstructions; Gaussian -> robust): the evaluation's standard noise
6.03 -> 5.89 cm and 2.10 -> 2.05 px; "mask mild" 10.2 -> 9.7 cm (window 3: 9.1 cm, but 2.36 px on
the standard noise). Most of the remaining mask error is front/back flips, which down-weighting
does not resolve (``silpose.model.hypotheses``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RobustSettings", "point_weights", "snap_correspondences"]


@dataclass(frozen=True)
class RobustSettings:
    """Settings of the robust loop (module doc).

    iterations: reweighting passes after the Gaussian one; threshold: c, in robust scales;
    scale_floor_px: added to the robust scale (keeps clean views from rejecting sub-pixel residuals);
    window: correspondence search half-width in contour points (0 = index correspondences).
    """

    iterations: int = 8
    threshold: float = 3.0
    scale_floor_px: float = 0.3
    window: int = 0

    def __post_init__(self) -> None:
        if int(self.iterations) < 1:
            raise ValueError(f"robust iterations must be >= 1, got {self.iterations}")
        if not self.threshold > 0 or not np.isfinite(self.threshold):
            raise ValueError(f"robust threshold must be finite and > 0, got {self.threshold}")
        if not self.scale_floor_px >= 0:
            raise ValueError(f"robust scale_floor_px must be >= 0, got {self.scale_floor_px}")
        if int(self.window) < 0:
            raise ValueError(f"robust window must be >= 0, got {self.window}")


def point_weights(residual_px: np.ndarray, threshold: float = 3.0, scale_floor_px: float = 0.3) -> np.ndarray:
    """Tukey biweights (..., n) in [0, 1] of per-point residuals (..., n) px, scale per contour (module doc).

    NaN residuals (absent views) give weight 0.
    """
    r = np.asarray(residual_px, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        med = np.median(r, axis=-1, keepdims=True)
        s = 1.4826 * med + scale_floor_px
        z = r / (threshold * np.maximum(s, 1e-12))
        u = np.where(z < 1.0, (1.0 - z * z) ** 2, 0.0)
    return np.where(np.isfinite(u), u, 0.0)


def snap_correspondences(observed_px: np.ndarray, recon_px: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """For each reconstructed point p, the nearest observed point among indices p - window .. p + window.

    observed_px, recon_px: (..., n, 2) closed contours (cyclic indices). Returns (matched (..., n, 2),
    distance (..., n) px). ``window`` = 0 keeps index correspondences.
    """
    obs = np.asarray(observed_px, dtype=np.float64)
    rec = np.asarray(recon_px, dtype=np.float64)
    if window <= 0:
        return obs, np.linalg.norm(obs - rec, axis=-1)
    n = obs.shape[-2]
    idx = (np.arange(n)[:, None] + np.arange(-window, window + 1)[None, :]) % n  # (n, 2w+1)
    cand = obs[..., idx, :]  # (..., n, 2w+1, 2)
    d2 = np.sum((cand - rec[..., :, None, :]) ** 2, axis=-1)
    j = np.argmin(np.where(np.isfinite(d2), d2, np.inf), axis=-1)
    matched = np.take_along_axis(cand, j[..., None, None], axis=-2)[..., 0, :]
    return matched, np.sqrt(np.take_along_axis(d2, j[..., None], axis=-1)[..., 0])
