"""Compiled loop of :mod:`silpose.model.untangle` (numba): each polygon's 2-opt moves, one polygon at a time.

:func:`silpose.model.untangle.untangle_orders` finds, round after round, every still-crossing polygon's first
crossing pair through a k-d tree of all polygons' edge midpoints: some twenty numpy calls per round, most of them
the calls' own overhead on a recording chunk's few dozen contours (``silpose infer --videos`` untangles every
reconstructed contour it draws: 1.8 ms per time step of the lab recording, the run's thread). Here a polygon's first
crossing pair is searched for directly -- edge i against the edges j > i + 1 in order, skipping a pair at once when
their boxes do not overlap -- and the first found is the k-d tree's first (the smallest i, then j), so the moves,
and the orders, are the same; the crossing test is :func:`silpose.model.untangle._orient`'s arithmetic, operation
for operation (``tests/model/test_untangle.py`` checks the orders against the numpy form and against a
one-pair-at-a-time reference). The module imports numba (about a second): :mod:`silpose.model.untangle` imports it
when it first untangles.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["untangle_orders_compiled"]


@njit(cache=True, nogil=True, inline="always")
def _orient(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:  # pragma: no cover
    """The sign of the turn a -> b -> c: (b - a) x (c - a), as :func:`silpose.model.untangle._orient`."""
    v = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    return 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)


@njit(cache=True, nogil=True)
def _first_crossing(p: np.ndarray, order: np.ndarray, xs: np.ndarray, ys: np.ndarray, lo_x: np.ndarray,
                    hi_x: np.ndarray, lo_y: np.ndarray, hi_y: np.ndarray) -> tuple[int, int]:  # pragma: no cover
    """(i, j), i < j, the first pair of non-adjacent edges of the closed polygon ``p[order]`` that cross properly
    (the smallest i, then the smallest j), or (-1, -1). xs, ys (n + 1,), lo_x ... hi_y (n,): scratch, filled here with
    the ordered points (the first repeated last) and the edges' boxes."""
    n = order.size
    for k in range(n):
        xs[k], ys[k] = p[order[k], 0], p[order[k], 1]
    xs[n], ys[n] = xs[0], ys[0]
    for k in range(n):
        lo_x[k], hi_x[k] = min(xs[k], xs[k + 1]), max(xs[k], xs[k + 1])
        lo_y[k], hi_y[k] = min(ys[k], ys[k + 1]), max(ys[k], ys[k + 1])
    for i in range(n - 2):
        x0, x1, y0, y1 = lo_x[i], hi_x[i], lo_y[i], hi_y[i]
        last = n - 1 if i > 0 else n - 2  # edge n - 1 -> 0 shares point 0 with edge 0
        for j in range(i + 2, last + 1):
            if hi_x[j] < x0 or lo_x[j] > x1 or hi_y[j] < y0 or lo_y[j] > y1:
                continue  # boxes apart: no crossing
            ax, ay, bx, by = xs[i], ys[i], xs[i + 1], ys[i + 1]
            cx, cy, dx, dy = xs[j], ys[j], xs[j + 1], ys[j + 1]
            if (_orient(ax, ay, bx, by, cx, cy) * _orient(ax, ay, bx, by, dx, dy) < 0
                    and _orient(cx, cy, dx, dy, ax, ay) * _orient(cx, cy, dx, dy, bx, by) < 0):
                return i, j
    return -1, -1


@njit(cache=True, nogil=True)
def untangle_orders_compiled(polygons: np.ndarray, max_moves: int) -> np.ndarray:  # pragma: no cover (compiled)
    """(B, n) int64 point orders that make each closed polygon of ``polygons`` (B, n, 2) float64 simple
    (:func:`silpose.model.untangle.untangle_orders`): the identity for polygons with a non-finite point, for those
    of fewer than 4 points and for simple ones; at most ``max_moves`` moves each."""
    B, n = polygons.shape[0], polygons.shape[1]
    out = np.empty((B, n), np.int64)
    xs, ys = np.empty(n + 1), np.empty(n + 1)
    lo_x, hi_x, lo_y, hi_y = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    for b in range(B):
        order = out[b]
        for k in range(n):
            order[k] = k
        if n < 4 or not np.all(np.isfinite(polygons[b])):
            continue
        p = polygons[b]
        for _ in range(max_moves):
            i, j = _first_crossing(p, order, xs, ys, lo_x, hi_x, lo_y, hi_y)
            if i < 0:
                break
            lo, hi = i + 1, j
            while lo < hi:
                order[lo], order[hi] = order[hi], order[lo]
                lo += 1
                hi -= 1
    return out
