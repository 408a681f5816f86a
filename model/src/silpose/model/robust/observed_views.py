"""The observed views of a batch that a reconstruction can be compared with, flattened for per-view repairs.

Robust inference's repairs of an observed contour against its reconstruction (``silpose.model.robust.excursions``,
``silpose.model.robust.reindex``) visit the same views: present, with finite points and a finite reconstruction.
:func:`observed_views` lists them once, with each view's normalisation scale (docs/conventions.md, "Contours":
the RMS distance of its points from their centroid), and holds the output the repairs write into.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ObservedViews", "observed_views"]


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


def observed_views(contours_px: np.ndarray, recon_px: np.ndarray, present: np.ndarray) -> ObservedViews:
    """The present views whose observed contour and reconstruction are finite.

    Args:
        contours_px: (N, K, n, 2) observed contours, px (absent views may hold NaN).
        recon_px: (N, K, n, 2) their reconstructions, px.
        present: (N, K) bool, observed views.
    """
    c = np.asarray(contours_px, dtype=np.float64)
    rec = np.asarray(recon_px, dtype=np.float64)
    present = np.asarray(present, dtype=bool)
    usable = present & np.isfinite(rec).all(axis=(2, 3)) & np.isfinite(c).all(axis=(2, 3))
    rows, views = np.nonzero(usable)
    pts, polys = c[rows, views], rec[rows, views]
    centred = pts - pts.mean(axis=1, keepdims=True)
    scales = np.sqrt(np.mean(np.sum(centred ** 2, axis=-1), axis=1)) if rows.size else np.zeros(0)
    return ObservedViews(c.copy(), np.zeros(present.shape, dtype=bool), rows, views, pts, polys, scales)
