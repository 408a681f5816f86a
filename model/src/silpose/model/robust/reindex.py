"""Re-indexing: a smooth shift of an observed contour's points along its outline, undone against a reconstruction.

Contours are resampled by arc length from the top of the head (docs/conventions.md, "Contours"), and the
model compares point i of the input with point i of its reconstruction. Anything that changes the length of
a stretch of outline -- a hole bitten into it, a blob or a shadow stuck to it, a head outline that moves the
start point -- slides every later point along the outline. Per-point robust weights (``silpose.model.robust``)
cannot undo a slide: the slid points lie *on* the body's outline, just at the wrong index. Excursion trimming
(``silpose.model.robust.excursions``) removes the loops that add many points, not the few points a bite adds.

:func:`reindex_contours` measures the slide against the robust reconstruction and resamples the input:

1. each observed point i is matched to the nearest reconstructed point among indices i - w .. i + w
   (``window``, a fraction of the n points), giving an offset ``d_i`` (points) and a distance ``e_i`` (px);
2. the slide is a smooth periodic function of the position along the outline,
   ``d(t) = a_0 + sum_{h <= H} (a_h cos h t + b_h sin h t)``, ``t = 2 pi i / n``, fitted by least squares
   on rows scaled by ``w_i = 1 / (1 + (e_i / sigma)^2)`` (``sigma`` a fraction of the view's scale), refitted
   twice without the points whose residual exceeds 3 robust scales;
3. the fit is used only when it is significant: ``chi2 = a^T (A^T W A) a / s^2 > min_chi2_per_point * n``,
   ``W = diag(w)``, ``s^2 = sum w r^2 / (sum w - 2H - 1)`` plus a floor (``offset_floor`` of the outline,
   squared);
   a clean input's reconstruction slides a little too, and the gate leaves most of that alone;
4. the input is resampled *by index* at ``i - d(i)`` (cyclic linear interpolation), so that its point i
   corresponds to reconstructed point i; the frame is then inferred again.

Low order (H = 3) is the point: a per-point search (``RobustSettings.window``, DTW) also absorbs real shape
differences along the outline and made clean inputs worse (robust module doc).

Chosen on the held-out part of the default preset's training split (200 walkers x 3 noise draws, robust
inference, M 15 q 40; mean pose error cm without -> with one pass, H 3, w 8/200, sigma 3/36, gate 0.6 n):

=================  ===========================  ==============  ==============  ==============
input              4 views                      3 views         2 views         1 view
=================  ===========================  ==============  ==============  ==============
"mask mild"        5.83 -> 5.45 (median 4.11 ->  7.36 -> 6.96    9.79 -> 9.48    15.35 -> 15.04
                   3.81)
standard noise     3.77 -> 3.77                 4.36 -> 4.37    5.78 -> 5.73    10.92 -> 10.93
clean              2.86 -> 2.84                 3.08 -> 3.08    3.65 -> 3.65    7.74 -> 7.76
"mask strong"      13.97 -> 13.95 (median 7.56 -> 7.32)
=================  ===========================  ==============  ==============  ==============

About two thirds of "mask mild" views are re-indexed, 5-8 % of standard-noise views (whose points the
evaluation moves along the normals, in place), 13-20 % of clean ones; robust inference of a batch takes
30-40 % longer (its changed frames are inferred again). Tried (applied outside the loop, on the same data):
H 2 without the gate, "mask mild" 5.12 but standard noise +0.05 (+0.34 with 2 views); H 0 (a cyclic shift
only), "mask mild" 5.59; gate 0.3 n, "mask mild" 5.36 and standard noise +0.02; two passes, no better than
one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .observed_views import observed_views
from .median import median_last

__all__ = ["ReindexSettings", "index_offsets", "fit_slide", "fit_slides", "solve_spd", "resample_by_index",
           "reindex_contours"]

#: views per block of :func:`fit_slides` in :func:`reindex_contours`
_BLOCK_VIEWS = 256


@dataclass(frozen=True)
class ReindexSettings:
    """Settings of :func:`reindex_contours` (module doc).

    window: search half-width, fraction of the n points (8 of 200);
    harmonics: H, the order of the periodic slide;
    sigma: distance scale of the match weights, fraction of the view's scale (RMS distance of its points
        from their centroid; 3 px of the default preset's ~36);
    min_chi2_per_point: significance gate, chi^2 per contour point;
    offset_floor: added to the residual scale of the offsets, fraction of the outline.
    """

    window: float = 8.0 / 200.0
    harmonics: int = 3
    sigma: float = 3.0 / 36.0
    min_chi2_per_point: float = 0.6
    offset_floor: float = 0.2236 / 200.0

    def __post_init__(self) -> None:
        for name in ("window", "sigma", "offset_floor"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"reindex {name} must be finite and > 0, got {v!r}")
        if not (np.isfinite(self.min_chi2_per_point) and self.min_chi2_per_point >= 0):
            raise ValueError(f"reindex min_chi2_per_point must be finite and >= 0, got {self.min_chi2_per_point!r}")
        if int(self.harmonics) < 0:
            raise ValueError(f"reindex harmonics must be >= 0, got {self.harmonics}")

    def window_points(self, n: int) -> int:
        """The search half-width in points for n-point contours (at least 1, below n / 2)."""
        return int(min(max(round(self.window * n), 1), max((n - 1) // 2, 1)))


def index_offsets(observed: np.ndarray, recon: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """For every observed point i, the nearest reconstructed point among indices i - window .. i + window (the first
    of equally near ones), by the compiled search :func:`silpose.model.robust.kernels.nearest_shifts`.

    Args:
        observed, recon: (V, n, 2) px.
        window: half-width in points.
    Returns:
        (offsets (V, n) int, the index difference j - i; distances (V, n) px).
    """
    from .kernels import nearest_shifts  # numba: imported on first use (module doc of .kernels)

    o = np.ascontiguousarray(observed, dtype=np.float64)
    r = np.ascontiguousarray(recon, dtype=np.float64)
    return nearest_shifts(o, r, int(window))


def _basis(n: int, harmonics: int) -> np.ndarray:
    """(n, 2H + 1) Fourier basis at t = 2 pi i / n: 1, cos t, sin t, ..., cos Ht, sin Ht."""
    t = 2.0 * np.pi * np.arange(n) / n
    cols = [np.ones(n)]
    for h in range(1, harmonics + 1):
        cols += [np.cos(h * t), np.sin(h * t)]
    return np.stack(cols, axis=1)


def fit_slide(offsets: np.ndarray, distances: np.ndarray, sigma_px: float, harmonics: int,
              floor_points: float) -> tuple[np.ndarray, float]:
    """The smooth periodic slide of one view (module doc, steps 2-3).

    Args:
        offsets: (n,) index offsets d_i, points.
        distances: (n,) match distances e_i, px.
        sigma_px: distance scale of the weights, px.
        harmonics: H.
        floor_points: floor of the offsets' residual scale, points.
    Returns:
        (slide (n,) points, chi2 of the fitted coefficients against zero).
    """
    d = np.asarray(offsets, dtype=np.float64)
    n = d.size
    A = _basis(n, harmonics)
    prior = 1.0 / (1.0 + (np.asarray(distances, dtype=np.float64) / sigma_px) ** 2)
    w = prior
    coef = np.zeros(A.shape[1])
    for _ in range(3):
        if w.sum() <= A.shape[1]:
            return np.zeros(n), 0.0
        coef = np.linalg.lstsq(A * w[:, None], d * w, rcond=None)[0]
        resid = d - A @ coef
        spread = 1.4826 * np.median(np.abs(resid)) + 0.5
        w = prior * (np.abs(resid) < 3.0 * spread)
    resid = d - A @ coef
    dof = max(w.sum() - A.shape[1], 1.0)
    s2 = float((w * resid ** 2).sum() / dof) + floor_points ** 2
    chi2 = float(coef @ ((A * w[:, None]).T @ A) @ coef / s2)
    return A @ coef, chi2


def fit_slides(offsets: np.ndarray, distances: np.ndarray, sigma_px: np.ndarray, harmonics: int,
               floor_points: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`fit_slide` of V views at once: offsets, distances (V, n), sigma_px (V,) -> (slides (V, n), chi2 (V,)).

    The weighted least squares are solved by their normal equations ``(A^T W^2 A) a = A^T W^2 d`` ((2H + 1)^2 per
    view; the Fourier basis keeps them well conditioned: any 2H + 1 distinct points give a regular system, and a
    live view has more than 2H + 1 points of positive weight) instead of one SVD per view: the same fit to rounding.
    """
    d = np.asarray(offsets, dtype=np.float64)
    v, n = d.shape
    A = _basis(n, harmonics)  # (n, p)
    p = A.shape[1]
    prior = 1.0 / (1.0 + (np.asarray(distances, dtype=np.float64) / np.asarray(sigma_px, dtype=np.float64)[:, None]) ** 2)
    w = prior
    coef = np.zeros((v, p))
    dead = np.zeros(v, dtype=bool)  # too little weight left: no slide (fit_slide returns zeros)
    outer = (A[:, :, None] * A[:, None, :]).reshape(n, p * p)  # A_i A_i^T per point
    for _ in range(3):
        dead |= w.sum(axis=1) <= p
        live = np.flatnonzero(~dead)
        if live.size == 0:
            break
        w2 = w[live] ** 2
        G = (w2 @ outer).reshape(live.size, p, p)
        rhs = (w2 * d[live]) @ A
        coef[live] = solve_spd(G, rhs)
        resid = d - coef @ A.T
        spread = 1.4826 * median_last(np.abs(resid)) + 0.5
        w = prior * (np.abs(resid) < 3.0 * spread[:, None])
    coef[dead] = 0.0
    resid = d - coef @ A.T
    dof = np.maximum(w.sum(axis=1) - p, 1.0)
    s2 = (w * resid ** 2).sum(axis=1) / dof + floor_points ** 2
    G1 = (w @ outer).reshape(v, p, p)  # A^T W A
    chi2 = np.einsum("vp,vpq,vq->v", coef, G1, coef) / s2
    chi2[dead] = 0.0
    return coef @ A.T, chi2


def solve_spd(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(V, p) solutions x of the symmetric positive definite systems ``G x = b``, G (V, p, p), b (V, p): one batched
    Cholesky factorisation ``G = L L^T`` and p steps of forward and back substitution, each over every system at once.

    ``np.linalg.solve`` on the stacked systems gives the same x to rounding (1e-15 relative on well-conditioned
    systems) but calls LAPACK once per small system, with OpenBLAS's threading around each call: 14 us per 7 x 7
    system on the 2-core machine against under 1 us here (``tests/model/test_reindex.py`` compares the two).
    """
    G = np.asarray(G, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    v, p = b.shape
    L = np.linalg.cholesky(G)
    y = np.empty((v, p))
    for i in range(p):  # L y = b
        y[:, i] = (b[:, i] - np.einsum("vk,vk->v", L[:, i, :i], y[:, :i])) / L[:, i, i]
    x = np.empty((v, p))
    for i in range(p - 1, -1, -1):  # L^T x = y
        x[:, i] = (y[:, i] - np.einsum("vk,vk->v", L[:, i + 1:, i], x[:, i + 1:])) / L[:, i, i]
    return x


def resample_by_index(points: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Closed contour ``points`` (n, 2) read at fractional, cyclic indices ``positions`` (m,) by linear
    interpolation between consecutive points; returns (m, 2)."""
    p = np.asarray(points, dtype=np.float64)
    n = len(p)
    pos = np.mod(np.asarray(positions, dtype=np.float64), n)
    i0 = np.floor(pos).astype(int) % n
    frac = (pos - np.floor(pos))[:, None]
    return p[i0] * (1.0 - frac) + p[(i0 + 1) % n] * frac


def reindex_contours(contours_px: np.ndarray, recon_px: np.ndarray, present: np.ndarray,
                     settings: ReindexSettings = ReindexSettings(),
                     scales: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Undo the significant slides of observed contours against their reconstructions (module doc); the
    arguments (``scales`` included) and the usable views are those of
    :func:`~silpose.model.robust.observed_views.observed_views`, and ``settings`` its thresholds.

    Returns:
        (contours (N, K, n, 2) float64, resampled by index where a slide was significant; changed (N, K) bool).
    """
    ov = observed_views(contours_px, recon_px, present, scales)
    n = ov.contours.shape[2]
    window = settings.window_points(n)
    gate = settings.min_chi2_per_point * n
    # the matches of every view (element-wise per view: in large blocks), then the fits in blocks of _BLOCK_VIEWS
    all_offsets, all_distances = index_offsets(ov.points, ov.recon, window)
    for start in range(0, ov.rows.size, _BLOCK_VIEWS):
        block = slice(start, start + _BLOCK_VIEWS)
        scales = ov.scales[block]
        usable = np.flatnonzero(scales > 0)
        if usable.size == 0:
            continue
        offsets, distances = all_offsets[start + usable], all_distances[start + usable]
        slides, chi2 = fit_slides(offsets, distances, settings.sigma * scales[usable], int(settings.harmonics),
                                  settings.offset_floor * n)
        for u in np.flatnonzero(chi2 > gate):
            j = start + int(usable[u])
            ov.set(j, resample_by_index(ov.points[j], np.arange(n) - slides[u]))
    return ov.contours, ov.changed
