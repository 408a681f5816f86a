"""Error measures, named after their protocol: the one home of pose error, Chamfer distance and mask IoU.

Paper §6 and docs/conventions.md, "Evaluation protocol".

- :func:`pose_error_cm` — the paper's pose error: mean Euclidean distance over the 19 joints,
  in cm, both skeletons root-relative (pelvis at the origin), no other alignment.
- :func:`pose_error_procrustes_cm` — a labelled EXTRA: the same after a similarity Procrustes
  alignment (rotation, uniform scale, translation; least squares, Umeyama 1991) of the
  prediction onto the truth. Not the paper's measure.
- :func:`mask_iou` — intersection over union of two silhouettes; two empty masks agree
  perfectly (1.0), one empty and one not give 0.0.
- :func:`chamfer_one_sided` — paper eq. 5, ``D(T, I) = 1/N sum_{f in T} d_T(f)``: T is the TRUE
  CLEAN contour rasterised 1 px wide, I the reconstructed contour rasterised the same way;
  d is the exact Euclidean distance from each pixel of T to the nearest pixel of I, read from
  ``cv2.distanceTransform(DIST_L2, DIST_MASK_PRECISE)`` of the inverted I image. Direction:
  true -> reconstruction. :func:`chamfer_errors` also returns the symmetric mean
  ``(D(T, I) + D(I, T)) / 2``.

Rasterisation uses :func:`silpose.shared.contours.draw_contour` on the image canvas enlarged by
:data:`CANVAS_MARGIN_PX` on every side, so a reconstruction that leaves the image slightly is
not clipped at the image border.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import cKDTree

from .contours import denormalise, draw_contour
from .skeleton import root_relative

__all__ = [
    "CANVAS_MARGIN_PX",
    "pose_error_cm",
    "procrustes_align",
    "pose_error_procrustes_cm",
    "chamfer_one_sided",
    "chamfer_errors",
    "place_contours",
    "mask_iou",
]

#: px added on each side of the image canvas before rasterising contours for Chamfer distances.
CANVAS_MARGIN_PX = 40


def _check_joints(a: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != 3 or a.shape[1:] != (19, 3):
        raise ValueError(f"{name} must have shape (N, 19, 3), got {a.shape}")
    return a


def pose_error_cm(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Paper pose error: mean over the 19 joints of ``||pred_j - true_j||``, root-relative, cm.

    Args:
        pred: (N, 19, 3) metres (root-relative or world: both are re-rooted at the pelvis).
        true: (N, 19, 3) metres.
    Returns:
        (N,) centimetres.
    """
    p = root_relative(_check_joints(pred, "pred"))
    t = root_relative(_check_joints(true, "true"))
    if p.shape != t.shape:
        raise ValueError(f"pred {p.shape} and true {t.shape} differ")
    return 100.0 * np.linalg.norm(p - t, axis=-1).mean(axis=-1)


def procrustes_align(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Similarity-align each ``pred`` onto ``true`` (least squares; Umeyama 1991).

    Minimises ``sum_j ||s R pred_j + t - true_j||^2`` over rotations R (det +1), scale s > 0 and
    translation t: with centred X (pred), Y (true), ``Y^T X = U S V^T``, ``R = U D V^T``,
    ``D = diag(1, 1, sign det(U V^T))``, ``s = tr(S D) / ||X||^2``.

    Args:
        pred, true: (N, J, 3).
    Returns:
        (N, J, 3) aligned prediction.
    """
    x = np.asarray(pred, dtype=np.float64)
    y = np.asarray(true, dtype=np.float64)
    mx, my = x.mean(axis=1, keepdims=True), y.mean(axis=1, keepdims=True)
    xc, yc = x - mx, y - my
    cov = np.einsum("nji,njk->nik", yc, xc)  # (N, 3, 3) = Y^T X
    u, s, vt = np.linalg.svd(cov)
    d = np.ones((len(x), 3))
    d[:, 2] = np.sign(np.linalg.det(u @ vt))
    d[d == 0] = 1.0
    rot = u @ (d[:, :, None] * vt)
    var_x = np.sum(xc * xc, axis=(1, 2))
    scale = np.divide(np.sum(s * d, axis=1), var_x, out=np.ones_like(var_x), where=var_x > 0)
    return scale[:, None, None] * np.einsum("nik,njk->nji", rot, xc) + my


def pose_error_procrustes_cm(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """EXTRA (not the paper's measure): mean joint distance after similarity Procrustes, cm.

    Args:
        pred, true: (N, 19, 3) metres.
    Returns:
        (N,) centimetres.
    """
    p = _check_joints(pred, "pred")
    t = _check_joints(true, "true")
    return 100.0 * np.linalg.norm(procrustes_align(p, t) - t, axis=-1).mean(axis=-1)


def _canvas(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Inclusive integer pixel bounds (x, y) of the enlarged canvas: lo = -margin, hi = size - 1 + margin."""
    m = CANVAS_MARGIN_PX
    return np.array([-m, -m]), np.array([width - 1 + m, height - 1 + m])


def _pixels_in(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(m, 2) integer (x, y) pixels of the closed contour ``points`` drawn on the window [lo, hi].

    Drawing on a window and shifting back is exact (cv2 fixed-point coordinates shift by whole
    pixels); a window that contains the contour's bounding box draws the same pixels as the
    whole canvas, so windows only save time.
    """
    size = hi - lo + 1
    img = draw_contour(np.asarray(points, dtype=np.float64) - lo, int(size[1]), int(size[0]))
    ys, xs = np.nonzero(img)
    return np.stack([xs + lo[0], ys + lo[1]], axis=1)


def _window(points: np.ndarray, height: int, width: int, extra: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Window around ``points`` (and the integer pixels ``extra``), 2 px of slack, within the canvas."""
    c_lo, c_hi = _canvas(height, width)
    p = np.asarray(points, dtype=np.float64)
    lo = np.floor(p.min(axis=0)) - 2
    hi = np.ceil(p.max(axis=0)) + 2
    if extra is not None and len(extra):
        lo = np.minimum(lo, extra.min(axis=0))
        hi = np.maximum(hi, extra.max(axis=0))
    lo = np.clip(lo, c_lo, c_hi).astype(int)
    hi = np.clip(hi, c_lo, c_hi).astype(int)
    return lo, hi


def _distance_to(img: np.ndarray) -> np.ndarray:
    """Exact Euclidean distance of every pixel to the nearest True pixel of ``img`` (H, W)."""
    inv = np.where(img, 0, 255).astype(np.uint8)
    return cv2.distanceTransform(inv, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)


def _true_pixels(true_px: np.ndarray, height: int, width: int) -> np.ndarray:
    lo, hi = _window(true_px, height, width)
    return _pixels_in(true_px, lo, hi)


def _one_sided(t_pix: np.ndarray, recon_px: np.ndarray, height: int, width: int) -> tuple[float, np.ndarray]:
    """D(T, I) from the true pixels ``t_pix`` (m, 2) to the contour ``recon_px``; also I's pixels."""
    lo, hi = _window(recon_px, height, width, extra=t_pix)
    size = hi - lo + 1
    r_img = draw_contour(np.asarray(recon_px, dtype=np.float64) - lo, int(size[1]), int(size[0]))
    if not r_img.any() or len(t_pix) == 0:
        return float("nan"), np.zeros((0, 2), int)
    dist = _distance_to(r_img)  # exact: every pixel of I lies inside the window
    d = float(dist[t_pix[:, 1] - lo[1], t_pix[:, 0] - lo[0]].mean())
    ys, xs = np.nonzero(r_img)
    return d, np.stack([xs + lo[0], ys + lo[1]], axis=1)


def chamfer_one_sided(true_px: np.ndarray, recon_px: np.ndarray, height: int, width: int) -> float:
    """Paper eq. 5, D(T, I): mean over the true contour's pixels of the distance to the nearest
    reconstructed-contour pixel.

    Args:
        true_px: (n, 2) true clean contour, px.
        recon_px: (m, 2) reconstructed contour, px.
        height, width: image size in px.
    Returns:
        Chamfer distance in px.
    """
    return _one_sided(_true_pixels(true_px, height, width), recon_px, height, width)[0]


def chamfer_errors(true_px: np.ndarray, recon_px: np.ndarray, image_size: tuple[int, int] | np.ndarray,
                   cache: dict | None = None, keys: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One-sided D(true -> recon) and symmetric mean Chamfer distances, per sample and view.

    Args:
        true_px: (N, K, n, 2) true clean contours, px.
        recon_px: (N, K, m, 2) reconstructions, px (NaN rows give NaN errors).
        image_size: (height, width) for all views, or (K, 2) per view.
        cache: optional dict reused across calls holding the true contours' pixel coordinates and
            a ``scipy.spatial.cKDTree`` of them (for the reverse direction D(I, T), equally
            exact), keyed by ``(keys[i], k)``.
        keys: (N,) sample identifiers for the cache (required with ``cache``).
    Returns:
        one_sided (N, K), symmetric (N, K), px.
    """
    t = np.asarray(true_px, dtype=np.float64)
    r = np.asarray(recon_px, dtype=np.float64)
    if t.ndim != 4 or r.ndim != 4 or t.shape[:2] != r.shape[:2]:
        raise ValueError(f"true_px {t.shape} and recon_px {r.shape} must be (N, K, n, 2) with equal N, K")
    n_samples, n_views = t.shape[:2]
    sizes = np.asarray(image_size, dtype=int)
    sizes = np.broadcast_to(sizes.reshape(-1, 2), (n_views, 2)) if sizes.size == 2 else sizes.reshape(n_views, 2)
    one = np.full((n_samples, n_views), np.nan)
    sym = np.full((n_samples, n_views), np.nan)
    for i in range(n_samples):
        for k in range(n_views):
            if not np.all(np.isfinite(r[i, k])):
                continue
            h, w = int(sizes[k, 0]), int(sizes[k, 1])
            key = None if cache is None else (int(keys[i]), k)
            if key is not None and key in cache:
                t_pix, t_tree = cache[key]
            else:
                t_pix = _true_pixels(t[i, k], h, w)
                t_tree = cKDTree(t_pix) if len(t_pix) else None
                if key is not None:
                    cache[key] = (t_pix, t_tree)
            if t_tree is None:
                continue
            d_tr, r_pix = _one_sided(t_pix, r[i, k], h, w)
            if not len(r_pix):
                continue
            one[i, k] = d_tr
            sym[i, k] = 0.5 * (d_tr + float(t_tree.query(r_pix)[0].mean()))
    return one, sym


def place_contours(contours_norm: np.ndarray, centroid: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Map normalised reconstructions to pixels with given normalisation factors.

    For a missing view these must be that view's TRUE (clean) factors (docs/conventions.md,
    "Evaluation protocol").

    Args:
        contours_norm: (N, K, n, 2); centroid: (N, K, 2) px; scale: (N, K) px.
    Returns:
        (N, K, n, 2) px.
    """
    return denormalise(np.asarray(contours_norm, np.float64), np.asarray(centroid, np.float64),
                       np.asarray(scale, np.float64))


def mask_iou(pred: np.ndarray, true: np.ndarray) -> np.ndarray | float:
    """Intersection over union of boolean masks; 1.0 where both are empty.

    Args:
        pred, true: (..., H, W) masks (nonzero = foreground), the same shape.
    Returns:
        a float for (H, W) inputs, else (...) float64 IoU per mask.
    """
    p, t = np.asarray(pred).astype(bool, copy=False), np.asarray(true).astype(bool, copy=False)
    if p.shape != t.shape or p.ndim < 2:
        raise ValueError(f"masks must have the same (..., H, W) shape, got {p.shape} and {t.shape}")
    inter = np.count_nonzero(p & t, axis=(-2, -1))
    union = np.count_nonzero(p | t, axis=(-2, -1))
    iou = np.where(union == 0, 1.0, inter / np.maximum(union, 1))
    return float(iou) if p.ndim == 2 else iou.astype(np.float64)
