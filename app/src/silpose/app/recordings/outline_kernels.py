"""Compiled loops of the silhouette fit (numba, :mod:`.silhouette_fit`): the nearest point of an outline.

:func:`nearest_on_outline` is :func:`.silhouette_fit.signed_distance`'s search and side test, point by point: a point's
candidate edges are a short loop over values in registers, where the numpy form gathered (points, edges, 2) arrays for
every call on a few hundred points (the fit calls it a few times per chunk of steps). The arithmetic is the numpy
form's, operation for operation (``tests/app/recordings/test_silhouette_fit.py`` checks it against
``cv2.pointPolygonTest``). numba is imported with this module (about a second): :mod:`.silhouette_fit` imports it when
the fit first runs.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from silpose.model.robust.kernels import segment_offset

__all__ = ["nearest_on_outline"]


@njit(cache=True, nogil=True)
def _normal(poly: np.ndarray, u: int, e: int, orientation: float) -> tuple[float, float]:  # pragma: no cover (compiled)
    """The outward unit normal of edge ``e -> e + 1`` (cyclic) of outline ``u`` of ``poly`` (U, n, 2); 0 when the edge
    has no length."""
    n = poly.shape[1]
    a = e % n
    b = (e + 1) % n
    dx = poly[u, b, 0] - poly[u, a, 0]
    dy = poly[u, b, 1] - poly[u, a, 1]
    length = np.sqrt(dx ** 2 + dy ** 2)
    if not length > 0:
        return 0.0, 0.0
    scale = orientation / length
    return dy * scale, -dx * scale


@njit(cache=True, nogil=True)
def nearest_on_outline(points: np.ndarray, poly: np.ndarray, which: np.ndarray, around: np.ndarray, window: int,
                       orientation: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover
    """Signed distance (M,) px, nearest outline point (M, 2) px and its edge (M,) of points (M, 2) to outlines
    ``poly`` (U, n, 2): point i on outline ``which[i]``, its edges ``around[i] - window .. around[i] + window`` (every
    edge, 0 .. n - 1, where ``around[i] < 0``); the first nearest candidate wins. The side: the outward normal of the
    nearest point's edge, plus its neighbour's at a vertex (``orientation`` (U,), the outlines' shoelace signs)."""
    m = points.shape[0]
    n = poly.shape[1]
    s = np.empty(m)
    near = np.empty((m, 2))
    edge = np.empty(m, dtype=np.int64)
    for i in range(m):
        u = which[i]
        px = points[i, 0]
        py = points[i, 1]
        if around[i] < 0:
            first, count = 0, n
        else:
            first, count = around[i] - window, 2 * window + 1
        best = np.inf
        be, bt, bx, by = 0, 0.0, 0.0, 0.0
        for c in range(count):
            e = (first + c) % n
            f = (e + 1) % n
            t, dx, dy = segment_offset(px, py, poly[u, e, 0], poly[u, e, 1], poly[u, f, 0], poly[u, f, 1])
            d2 = dx * dx + dy * dy
            if d2 < best:
                best, be, bt = d2, e, t
                bx = poly[u, e, 0] + t * (poly[u, f, 0] - poly[u, e, 0])
                by = poly[u, e, 1] + t * (poly[u, f, 1] - poly[u, e, 1])
        ox = px - bx
        oy = py - by
        dist = np.sqrt(ox ** 2 + oy ** 2)
        o = orientation[u]
        nx, ny = _normal(poly, u, be, o)
        if bt <= 0.0:
            qx, qy = _normal(poly, u, be - 1 + n, o)
            nx, ny = nx + qx, ny + qy
        if bt >= 1.0:
            qx, qy = _normal(poly, u, be + 1, o)
            nx, ny = nx + qx, ny + qy
        s[i] = dist if ox * nx + oy * ny > 0 else -dist
        near[i, 0] = bx
        near[i, 1] = by
        edge[i] = be
    return s, near, edge
