"""The observed views of a batch that a reconstruction can be compared with, flattened for per-view repairs.

Robust inference's repairs of an observed contour against its reconstruction (``silpose.model.robust.excursions``,
``silpose.model.robust.reindex``) visit the same views: present, with finite points and a finite reconstruction.
:func:`observed_views` lists them once, with each view's normalisation scale (docs/conventions.md, "Contours":
the RMS distance of its points from their centroid), and holds the output the repairs write into.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ObservedViews", "observed_views", "view_scales"]

#: views from which :func:`view_scales` sums point by point (fewer: numpy's formula, one call per step)
_LOOP_VIEWS = 64


@dataclass
class ObservedViews:
    """Usable views of an (N, K) batch of n-point contours, V of them.

    Attributes:
        contours: (N, K, n, 2) float64 copy of the observed contours, px: the repairs write here.
        changed: (N, K) bool, views a repair changed (all False at first).
        rows, views: (V,) frame and view index of each usable view.
        points: (V, n, 2) its observed contour, px.
        recon: (V, n, 2) its reconstruction, px.
        scales: (V,) its normalisation scale, px.
    """

    contours: np.ndarray
    changed: np.ndarray
    rows: np.ndarray
    views: np.ndarray
    points: np.ndarray
    recon: np.ndarray
    scales: np.ndarray

    def set(self, j: int, contour: np.ndarray) -> None:
        """Write the repaired contour (n, 2) of usable view ``j`` and mark it changed."""
        self.contours[self.rows[j], self.views[j]] = contour
        self.changed[self.rows[j], self.views[j]] = True


def observed_views(contours_px: np.ndarray, recon_px: np.ndarray, present: np.ndarray,
                   scales: np.ndarray | None = None) -> ObservedViews:
    """The present views whose observed contour and reconstruction are finite.

    Args:
        contours_px: (N, K, n, 2) observed contours, px (absent views may hold NaN).
        recon_px: (N, K, n, 2) their reconstructions, px.
        present: (N, K) bool, observed views.
        scales: (N, K) px, the :func:`view_scales` of ``contours_px`` when the caller knows them (robust inference
            keeps them from one repair to the next: they depend on the observed points only); None = computed here.
    """
    c = np.asarray(contours_px, dtype=np.float64)
    rec = np.asarray(recon_px, dtype=np.float64)
    present = np.asarray(present, dtype=bool)
    usable = present & np.isfinite(rec).all(axis=(2, 3)) & np.isfinite(c).all(axis=(2, 3))
    rows, views = np.nonzero(usable)
    if rows.size == usable.size:  # every view: views of the arrays, no copies
        pts, polys = c.reshape(-1, *c.shape[2:]), rec.reshape(-1, *rec.shape[2:])
    else:
        pts, polys = c[rows, views], rec[rows, views]
    sc = view_scales(pts) if scales is None else np.asarray(scales, dtype=np.float64)[rows, views]
    return ObservedViews(c.copy(), np.zeros(present.shape, dtype=bool), rows, views, pts, polys, sc)


def view_scales(points: np.ndarray) -> np.ndarray:
    """(V,) RMS distance of each view's points (V, n, 2) from their centroid, px (docs/conventions.md, "Contours").

    The arithmetic of ``sqrt(mean(sum((p - p.mean(axis=1)) ** 2, axis=-1), axis=1))``, bit for bit: the centroid is
    the same sequential sum over the points, the squares are summed per coordinate, without numpy's reductions over
    an axis of 2 (which dominated the repairs' cost on large batches).
    """
    v, n = points.shape[:2]
    if v < _LOOP_VIEWS or n == 0:  # few views: the numpy formula itself (the loop's 2n calls would cost more)
        centred = points - points.mean(axis=1, keepdims=True)
        return np.sqrt(np.mean(np.sum(centred ** 2, axis=-1), axis=1)) if v else np.zeros(0)
    x, y = points[..., 0], points[..., 1]
    xt, yt = np.ascontiguousarray(x.T), np.ascontiguousarray(y.T)  # (n, V): each point's row read contiguously
    sx, sy = xt[0].copy(), yt[0].copy()
    for i in range(1, n):  # np.mean over axis 1 of (V, n, 2) adds the points in order, as here
        sx += xt[i]
        sy += yt[i]
    cx, cy = x - (sx / n)[:, None], y - (sy / n)[:, None]
    return np.sqrt(np.mean(cx * cx + cy * cy, axis=1))
