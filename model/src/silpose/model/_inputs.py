"""Input checks and fast contour normalisation for :class:`~silpose.model.shape_model.ShapeStructureModel`."""

from __future__ import annotations

import numpy as np


def normalise_contours(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``silpose.shared.contours.normalise`` in float64, arranged for speed (same definition).

    centroid c = mean of the points, scale s = RMS distance from c, q = (p - c) / s, and q = 0 with
    s = 0 for a degenerate contour. points (..., n, 2) px -> (q (..., n, 2), c (..., 2), s (...,)).
    """
    p = np.asarray(points, dtype=np.float64)
    lead, n = p.shape[:-2], p.shape[-2]
    f = p.reshape(-1, n, 2)
    c = np.stack([f[:, :, 0].sum(axis=1), f[:, :, 1].sum(axis=1)], axis=-1) / n  # strided sums: fast
    q = f - c[:, None, :]
    flat = q.reshape(q.shape[0], -1)
    s = np.sqrt(np.einsum("ij,ij->i", flat, flat) / n)
    q /= np.where(s > 0, s, 1.0)[:, None, None]
    return q.reshape(p.shape), c.reshape(*lead, 2), s.reshape(lead)


def denormalise_contours(q: np.ndarray, centroid: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Inverse of :func:`normalise_contours` (``silpose.shared.contours.denormalise``): ``p = s q + c``, float64."""
    out = q * np.asarray(scale, dtype=np.float64)[..., None, None]
    out += np.asarray(centroid, dtype=np.float64)[..., None, :]
    return out


def check_contours(contours: np.ndarray, name: str, n_points: int | None = None) -> np.ndarray:
    raw = np.asarray(contours)
    if np.iscomplexobj(raw):
        raise ValueError(f"{name} must be real pixel coordinates, got dtype {raw.dtype}")
    try:
        c = raw.astype(np.float64, copy=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric pixel coordinates, got dtype {raw.dtype} ({exc})") from None
    if c.ndim != 4 or c.shape[-1] != 2 or c.shape[1] < 1:
        raise ValueError(f"{name} must have shape (N, K, n, 2), got {c.shape}")
    if c.shape[0] == 0:
        raise ValueError(f"{name} is empty (N = 0)")
    if n_points is not None and c.shape[2] != n_points:
        raise ValueError(f"{name} has {c.shape[2]} points per contour, the model expects {n_points}")
    return c


def check_present(views_present, n: int, k_in: int) -> np.ndarray:
    if views_present is None:
        return np.ones((n, k_in), dtype=bool)
    p = np.asarray(views_present)
    if p.shape != (n, k_in):
        raise ValueError(f"views_present must have shape ({n}, {k_in}), got {p.shape}")
    if p.dtype != bool:
        if not np.isin(p, (0, 1)).all():
            raise ValueError("views_present must be boolean (or 0/1)")
        p = p.astype(bool)
    return p


def check_factors(centroid, scale, n: int, k_in: int):
    if centroid is None and scale is None:
        return None, None
    if centroid is None or scale is None:
        raise ValueError("pass both centroid and scale, or neither")
    cen = np.asarray(centroid, dtype=np.float64)
    sc = np.asarray(scale, dtype=np.float64)
    if cen.shape != (n, k_in, 2):
        raise ValueError(f"centroid must have shape ({n}, {k_in}, 2), got {cen.shape}")
    if sc.shape != (n, k_in):
        raise ValueError(f"scale must have shape ({n}, {k_in}), got {sc.shape}")
    return cen, sc
