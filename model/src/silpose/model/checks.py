"""Input checks of :class:`~silpose.model.shape_model.ShapeStructureModel`: contours, view flags,
normalisation factors, the modelled views. Each raises ValueError naming the argument and the expected shape."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Inputs:
    """Observed contours in the model's view order (:func:`model_inputs`).

    present (N, K) bool; contours (N, K, n, 2) px (absent views may hold NaN); centroid (N, K, 2) and scale
    (N, K): the true normalisation factors where given (NaN otherwise), used for absent views.
    """

    present: np.ndarray
    contours: np.ndarray
    centroid: np.ndarray
    scale: np.ndarray

    def take(self, rows) -> "Inputs":
        return Inputs(self.present[rows], self.contours[rows], self.centroid[rows], self.scale[rows])

    def with_contours(self, contours: np.ndarray) -> "Inputs":
        return Inputs(self.present, contours, self.centroid, self.scale)


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


def check_views(views, n_rig: int) -> tuple[int, ...]:
    """The rig views a model fits (``views`` None = all ``n_rig``), each checked to exist."""
    out = tuple(range(n_rig)) if views is None else tuple(int(v) for v in views)
    bad = [v for v in out if not 0 <= v < n_rig]
    if bad:
        raise ValueError(f"views {bad} do not exist: the data have {n_rig} views (0..{n_rig - 1})")
    return out


def input_columns(layout, n_rig_views: int, k_in: int, input_views) -> np.ndarray:
    """(K_mod,) input column of each of ``layout``'s modelled views, -1 when the input does not contain it.

    ``input_views``: rig indices of the K_in input columns; None = the rig's views (K_in = ``n_rig_views``) or
    the modelled views (K_in = their number), in order."""
    if input_views is None:
        if k_in == n_rig_views:
            input_views = tuple(range(k_in))
        elif k_in == layout.n_views:
            input_views = layout.views
        else:
            raise ValueError(
                f"contours_px has {k_in} views; expected {layout.n_views} (the modelled views "
                f"{layout.views}) or {n_rig_views} (all rig views), or pass input_views"
            )
    input_views = [int(v) for v in input_views]
    if len(input_views) != k_in:
        raise ValueError(f"input_views names {len(input_views)} views but contours_px has {k_in}")
    unknown = [v for v in input_views if not 0 <= v < n_rig_views]
    if unknown:
        raise ValueError(f"unknown view indices {unknown}: the model's rig has views 0..{n_rig_views - 1}")
    if len(set(input_views)) != len(input_views):
        raise ValueError(f"input_views has duplicates: {input_views}")
    return np.array([input_views.index(v) if v in input_views else -1 for v in layout.views])


def model_inputs(layout, n_rig_views: int, contours_px, views_present, input_views, centroid, scale) -> Inputs:
    """The arguments of ``ShapeStructureModel.infer`` as :class:`Inputs` in the model's
    view order; shapes and values checked (an observed view must be finite, every frame needs one)."""
    c_in = check_contours(contours_px, "contours_px", n_points=layout.n_points)
    n, k_in = c_in.shape[:2]
    cols = input_columns(layout, n_rig_views, k_in, input_views)
    present_in = check_present(views_present, n, k_in)
    kmod = layout.n_views
    cen_in, sc_in = check_factors(centroid, scale, n, k_in)
    if np.array_equal(cols, np.arange(k_in)):  # input columns are the modelled views, in order: no copies
        present, c_mod = present_in, c_in
        cen_true = cen_in if cen_in is not None else np.full((n, kmod, 2), np.nan)
        sc_true = sc_in if sc_in is not None else np.full((n, kmod), np.nan)
    else:
        present = np.zeros((n, kmod), dtype=bool)
        c_mod = np.full((n, kmod, layout.n_points, 2), np.nan)
        cen_true = np.full((n, kmod, 2), np.nan)
        sc_true = np.full((n, kmod), np.nan)
        for p, col in enumerate(cols):
            if col < 0:
                continue
            present[:, p] = present_in[:, col]
            c_mod[:, p] = c_in[:, col]
            if cen_in is not None:
                cen_true[:, p] = cen_in[:, col]
                sc_true[:, p] = sc_in[:, col]
    all_present = bool(present.all())
    finite = np.isfinite(c_mod).all() if all_present else np.isfinite(c_mod).all(axis=(2, 3))[present].all()
    if not finite:
        bad = ~np.isfinite(c_mod).all(axis=(2, 3)) & present
        r, p = np.argwhere(bad)[0]
        raise ValueError(
            f"contours_px has NaN/inf in an observed view: frame {r}, view {layout.views[p]} "
            f"({int(bad.sum())} observed views affected); mark such views absent in views_present"
        )
    none = ~present.any(axis=1)
    if none.any():
        raise ValueError(
            f"every modelled view is missing in {int(none.sum())} frame(s) (first: frame "
            f"{int(np.flatnonzero(none)[0])}); at least one of views {layout.views} must be observed"
        )
    return Inputs(present, c_mod, cen_true, sc_true)
