"""Self-intersections of reconstructed contours, and their removal by 2-opt moves.

A reconstruction ``mu + W x`` is a linear combination of contours, so nothing keeps it a simple
polygon: where the outline runs along a thin gap (between the legs, under an arm) its two sides
can cross. Measured on the default preset (500 test walkers, the evaluation's standard noise):
42 % of the 4-view reconstructions and 64 % of missing-view reconstructions self-intersect,
although no true contour does.

:func:`self_intersecting` tests the pairs of non-adjacent edges of a closed polygon that are close
enough to meet (a k-d tree of the edge midpoints) for a proper crossing (orientation signs). :func:`untangle` removes the crossings the way
2-opt does for a travelling-salesman tour: for crossing edges (p_i, p_i+1) and (p_j, p_j+1) the
points p_i+1 .. p_j are visited in reverse order, which replaces the two edges by (p_i, p_j) and
(p_i+1, p_j+1) -- uncrossed and strictly shorter (triangle inequality), so the loop ends. Points
keep their positions; only the order of a twisted stretch is reversed, and the first point (the
contour's start, docs/conventions.md, "Contours") stays first. The moves are a compiled loop per polygon
(:mod:`.untangle_kernels`: its first crossing pair searched for edge by edge, boxes first), 7x faster than rounds of
:func:`batch_crossings` over the batch (the lab recording's 1,160 reconstructed contours: 26 against 190-200 us a
contour), with the same orders.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["batch_crossings", "self_intersecting", "crossing_pairs", "untangle", "untangle_order", "untangle_orders"]

MAX_MOVES = 200  # 2-opt moves per contour before giving up (never reached in practice)


def _orient(p, q, r) -> np.ndarray:
    return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))


def batch_crossings(polygons: np.ndarray) -> np.ndarray:
    """(m, 3) rows (polygon b, edge i, edge j), i < j, of the edge pairs that cross properly in each closed
    polygon of ``polygons`` (B, n, 2), sorted by b, then i, then j.

    Edge e joins p_e and p_e+1 (cyclic). Two edges can only cross when their midpoints are closer than
    the polygon's longest edge L (each midpoint is within half its edge of the crossing), so candidate
    pairs come from one k-d tree of every polygon's midpoints in units of its own L (``query_pairs`` at
    radius 1), the polygons 4 units apart along a third axis so that no pair joins two of them; only the
    candidates get the orientation test: ~O(Bn log Bn) for all B polygons at once, instead of n^2 / 2 pairs
    each. Polygons with NaN points, and those of fewer than 4 points, have no pairs.
    """
    p = np.asarray(polygons, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 2:
        raise ValueError(f"polygons must have shape (B, n, 2), got {p.shape}")
    n = p.shape[1]
    keep_b = np.flatnonzero(np.isfinite(p).all(axis=(1, 2))) if n >= 4 else np.zeros(0, np.intp)
    if len(keep_b) == 0:
        return np.zeros((0, 3), dtype=np.intp)
    p = p[keep_b]
    q = np.roll(p, -1, axis=1)
    longest = np.linalg.norm(q - p, axis=2).max(axis=1)  # (B,)
    unit = np.where(longest > 0, longest, 1.0)
    mid = 0.5 * (p + q) / unit[:, None, None]
    layer = np.broadcast_to(4.0 * np.arange(len(p), dtype=np.float64)[:, None, None], (len(p), n, 1))
    cand = cKDTree(np.concatenate([mid, layer], axis=2).reshape(-1, 3)).query_pairs(1.0 + 1e-9, output_type="ndarray")
    if len(cand) == 0:
        return np.zeros((0, 3), dtype=np.intp)
    b = cand[:, 0] // n
    i, j = np.minimum(cand[:, 0], cand[:, 1]) % n, np.maximum(cand[:, 0], cand[:, 1]) % n
    keep = (b == cand[:, 1] // n) & (j - i > 1) & ~((i == 0) & (j == n - 1))  # adjacent edges share a point
    b, i, j = b[keep], i[keep], j[keep]
    a, bb, c, d = p[b, i], q[b, i], p[b, j], q[b, j]
    hit = (_orient(a, bb, c) * _orient(a, bb, d) < 0) & (_orient(c, d, a) * _orient(c, d, bb) < 0)
    out = np.stack([keep_b[b[hit]], i[hit], j[hit]], axis=1)
    return out[np.lexsort((out[:, 2], out[:, 1], out[:, 0]))]


def crossing_pairs(points: np.ndarray) -> np.ndarray:
    """(m, 2) edge index pairs (i < j) that cross properly in one closed polygon ``points`` (n, 2), sorted
    (:func:`batch_crossings` of one polygon). NaN points: no pairs."""
    p = np.asarray(points, dtype=np.float64)
    return batch_crossings(p[None])[:, 1:] if p.ndim == 2 else batch_crossings(p)


def self_intersecting(contours: np.ndarray) -> np.ndarray:
    """(...,) bool: the closed polygon (..., n, 2) has two non-adjacent edges that cross properly.

    Touching edges (a zero orientation) do not count. A polygon with NaN coordinates gives False.
    """
    c = np.asarray(contours, dtype=np.float64)
    if c.ndim < 2 or c.shape[-1] != 2:
        raise ValueError(f"contours must have shape (..., n, 2), got {c.shape}")
    lead, n = c.shape[:-2], c.shape[-2]
    out = np.zeros(int(np.prod(lead, dtype=np.int64)), dtype=bool)
    out[batch_crossings(c.reshape(-1, n, 2))[:, 0]] = True
    return out.reshape(lead)


def untangle_orders(polygons: np.ndarray) -> np.ndarray:
    """(B, n) point orders that make each closed polygon of ``polygons`` (B, n, 2) simple by 2-opt moves
    (module doc): each polygon, again and again, reverses the stretch of its first crossing pair (the smallest i,
    then j: :func:`batch_crossings`'s order); the identity for a simple polygon and for one with NaN points; at most
    :data:`MAX_MOVES` moves each. Compiled (:mod:`.untangle_kernels`, imported on the first call)."""
    from .untangle_kernels import untangle_orders_compiled

    p = np.ascontiguousarray(polygons, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 2:
        raise ValueError(f"polygons must have shape (B, n, 2), got {p.shape}")
    return untangle_orders_compiled(p, MAX_MOVES)


def untangle_order(points: np.ndarray) -> np.ndarray:
    """(n,) point order that makes the closed polygon ``points`` (n, 2) simple by 2-opt moves (module doc).

    Returns the identity when it already is; stops after :data:`MAX_MOVES` moves.
    """
    return untangle_orders(np.asarray(points, dtype=np.float64)[None])[0]


def untangle(contours: np.ndarray, *others: np.ndarray) -> tuple[np.ndarray, ...]:
    """Make every closed polygon of ``contours`` (..., n, 2) simple; apply the same reordering to ``others``.

    Returns (untangled contours, *reordered others), new arrays. ``others`` have the same leading
    shape and n (e.g. the same reconstructions in pixels while ``contours`` are normalised: crossings
    are invariant to a similarity transform). Polygons with NaN are left as they are (:func:`untangle_orders`).
    """
    c = np.array(contours, dtype=np.float64)
    outs = [np.array(o, dtype=np.float64) for o in others]
    lead, n = c.shape[:-2], c.shape[-2]
    flat = c.reshape(-1, n, 2)
    flat_others = [o.reshape(-1, n, o.shape[-1]) for o in outs]
    order = untangle_orders(flat)
    tangled = np.flatnonzero((order != np.arange(n)).any(axis=1))
    if len(tangled):
        order = order[tangled]
        flat[tangled] = np.take_along_axis(flat[tangled], order[..., None], axis=1)
        for o in flat_others:
            o[tangled] = np.take_along_axis(o[tangled], order[..., None], axis=1)
    return (flat.reshape(c.shape), *[fo.reshape(o.shape) for fo, o in zip(flat_others, outs)])
