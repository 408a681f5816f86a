"""Input checks of :class:`~silpose.model.shape_model.ShapeStructureModel`: contours, view flags,
normalisation factors. Each raises ValueError naming the argument and the expected shape."""

from __future__ import annotations

import numpy as np


def check_contours(contours, name: str, n_points: int | None = None) -> np.ndarray:
    """``contours`` as a float64 array (N, K, n, 2) of pixel coordinates (N >= 1, K >= 1); ``n_points``
    checks n. Values are not checked here (absent views may hold NaN)."""
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
    """(n, k_in) bool view flags; None = every view present; 0/1 integers are accepted."""
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
    """(centroid (n, k_in, 2), scale (n, k_in)) float64 pixel normalisation factors, or (None, None)."""
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
