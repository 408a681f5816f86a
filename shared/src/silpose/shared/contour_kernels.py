"""Compiled loops of contour extraction (numba, :mod:`.contours`): the start point and the arc-length resampling.

:func:`start_on_polyline` and :func:`resample_closed` are the two steps that turn a traced outline (a few hundred
vertices) into the model's ``n`` points (docs/conventions.md, "Contours"). As numpy calls they were some twenty array
operations each on a few hundred values -- about 0.1 ms a contour, most of it the calls' own overhead, and a
recording makes several contours per time step. Here each is one pass over the vertices, with the arithmetic of the
numpy form operation for operation (the same answers bit for bit on the lab recording's outlines;
``tests/shared/test_contours.py`` checks both against a segment-by-segment walk). numba is imported with this module
(about a second); :mod:`.contours` imports it when the first contour is traced. ``nogil``: camera threads trace at
once.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["start_on_polyline", "resample_closed", "chain_outline"]


@njit(cache=True, nogil=True)
def start_on_polyline(poly: np.ndarray, cx: float) -> tuple[int, np.ndarray]:  # pragma: no cover (compiled)
    """Farthest-up crossing of the closed polyline ``poly`` (m, 2) float64 (edge m-1 -> 0 implied) with the vertical
    line ``x = cx``: (i, p), the crossing on edge i -> i+1 (mod m) at point p (2,). An edge lying on the line counts
    with its upper end; ties go to the first edge. Without any crossing (degenerate outlines) the vertex nearest to
    the line, topmost among ties, first among those, with its outgoing edge."""
    m = poly.shape[0]
    best, best_y, best_t = -1, np.inf, 0.0
    for i in range(m):
        j = i + 1 if i + 1 < m else 0
        ax, ay, bx, by = poly[i, 0], poly[i, 1], poly[j, 0], poly[j, 1]
        if min(ax, bx) <= cx <= max(ax, bx):
            dx = bx - ax
            t = (1.0 if by < ay else 0.0) if dx == 0 else (cx - ax) / dx
            y = ay + t * (by - ay)
            if y < best_y or best < 0:
                best, best_y, best_t = i, y, t
    out = np.empty(2)
    if best >= 0:
        j = best + 1 if best + 1 < m else 0
        out[0] = poly[best, 0] + best_t * (poly[j, 0] - poly[best, 0])
        out[1] = poly[best, 1] + best_t * (poly[j, 1] - poly[best, 1])
        return best, out
    best, best_d, best_y = 0, np.inf, np.inf
    for i in range(m):
        d = abs(poly[i, 0] - cx)
        if d < best_d or (d == best_d and poly[i, 1] < best_y):
            best, best_d, best_y = i, d, poly[i, 1]
    out[0], out[1] = poly[best, 0], poly[best, 1]
    return best, out


@njit(cache=True, nogil=True)
def resample_closed(poly: np.ndarray, start_edge: int, start: np.ndarray, n_points: int) -> np.ndarray:  # pragma: no cover
    """``n_points`` points (n_points, 2) float64 equally spaced in arc length along the closed polyline ``poly``
    (m, 2) (edge m-1 -> 0 implied), point k at arc length ``k L / n_points`` from ``start`` (2,) on edge
    ``start_edge`` -> +1, in the polyline's direction; linear interpolation as ``np.interp``'s (L = perimeter; a
    zero-length outline gives n copies of ``start``)."""
    m = poly.shape[0]
    path = np.empty((m + 2, 2))  # the start, the vertices after it once round, the start again
    path[0, 0], path[0, 1] = start[0], start[1]
    for k in range(m):
        v = start_edge + 1 + k
        v = v - m if v >= m else v
        path[k + 1, 0], path[k + 1, 1] = poly[v, 0], poly[v, 1]
    path[m + 1, 0], path[m + 1, 1] = start[0], start[1]
    s = np.empty(m + 2)  # arc length at each path vertex (a running sum, as np.cumsum's)
    s[0] = 0.0
    acc = 0.0
    for k in range(m + 1):
        acc += np.hypot(path[k + 1, 0] - path[k, 0], path[k + 1, 1] - path[k, 1])
        s[k + 1] = acc
    total = s[m + 1]
    out = np.empty((n_points, 2))
    if not total > 0:
        for k in range(n_points):
            out[k, 0], out[k, 1] = start[0], start[1]
        return out
    step = total / n_points
    j = 0  # the last path vertex at or before the target (np.interp's interval; targets rise)
    for k in range(n_points):
        t = k * step
        while j + 2 < m + 2 and s[j + 1] <= t:
            j += 1
        dx = s[j + 1] - s[j]
        for c in range(2):
            slope = (path[j + 1, c] - path[j, c]) / dx
            out[k, c] = slope * (t - s[j]) + path[j, c]
    return out


@njit(cache=True, nogil=True)
def chain_outline(chain: np.ndarray, reverse: bool, ox: float, oy: float, cx: float,
                  n_points: int) -> np.ndarray:  # pragma: no cover (compiled)
    """A traced outline ``chain`` (m, 2) int32 (``cv2.findContours``' points, read backwards with ``reverse``),
    moved by (``ox``, ``ox``) px, started at the farthest-up crossing with ``x = cx`` and resampled:
    (n_points, 2) float64 px."""
    m = chain.shape[0]
    poly = np.empty((m, 2))
    for k in range(m):
        r = m - 1 - k if reverse else k
        poly[k, 0] = chain[r, 0] + ox
        poly[k, 1] = chain[r, 1] + oy
    i, start = start_on_polyline(poly, cx)
    return resample_closed(poly, i, start, n_points)
