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
contour's start, docs/conventions.md, "Contours") stays first.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["self_intersecting", "crossing_pairs", "untangle", "untangle_order"]

MAX_MOVES = 200  # 2-opt moves per contour before giving up (never reached in practice)


def _orient(p, q, r) -> np.ndarray:
    return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))


def crossing_pairs(points: np.ndarray) -> np.ndarray:
    """(m, 2) edge index pairs (i < j) that cross properly in one closed polygon ``points`` (n, 2).

    Edge e joins p_e and p_e+1 (cyclic). Two edges can only cross when their midpoints are closer than
    the longest edge, so candidate pairs come from a k-d tree of the midpoints (``query_pairs``) and
    only those get the orientation test: ~O(n log n) instead of n^2 / 2 pairs. NaN points: no pairs.
    """
    p = np.asarray(points, dtype=np.float64)
    n = len(p)
    if n < 4 or not np.all(np.isfinite(p)):
        return np.zeros((0, 2), dtype=np.intp)
    q = np.roll(p, -1, axis=0)
    length = np.linalg.norm(q - p, axis=1)
    cand = cKDTree(0.5 * (p + q)).query_pairs(float(length.max()) * (1.0 + 1e-9), output_type="ndarray")
    if len(cand) == 0:
        return np.zeros((0, 2), dtype=np.intp)
    i, j = np.minimum(cand[:, 0], cand[:, 1]), np.maximum(cand[:, 0], cand[:, 1])
    keep = (j - i > 1) & ~((i == 0) & (j == n - 1))  # adjacent edges share a point: not a crossing
    i, j = i[keep], j[keep]
    a, b, c, d = p[i], q[i], p[j], q[j]
    hit = (_orient(a, b, c) * _orient(a, b, d) < 0) & (_orient(c, d, a) * _orient(c, d, b) < 0)
    out = np.stack([i[hit], j[hit]], axis=1)
    return out[np.lexsort((out[:, 1], out[:, 0]))]


def self_intersecting(contours: np.ndarray) -> np.ndarray:
    """(...,) bool: the closed polygon (..., n, 2) has two non-adjacent edges that cross properly.

    Touching edges (a zero orientation) do not count. A polygon with NaN coordinates gives False.
    """
    c = np.asarray(contours, dtype=np.float64)
    if c.ndim < 2 or c.shape[-1] != 2:
        raise ValueError(f"contours must have shape (..., n, 2), got {c.shape}")
    lead, n = c.shape[:-2], c.shape[-2]
    flat = c.reshape(-1, n, 2)
    out = np.array([len(crossing_pairs(poly)) > 0 for poly in flat], dtype=bool)
    return out.reshape(lead)


def untangle_order(points: np.ndarray) -> np.ndarray:
    """(n,) point order that makes the closed polygon ``points`` (n, 2) simple by 2-opt moves (module doc).

    Returns the identity when it already is; stops after :data:`MAX_MOVES` moves.
    """
    p = np.asarray(points, dtype=np.float64)
    order = np.arange(len(p))
    for _ in range(MAX_MOVES):
        hits = crossing_pairs(p[order])
        if len(hits) == 0:
            break
        i, j = hits[0]
        order[i + 1 : j + 1] = order[i + 1 : j + 1][::-1]
    return order


def untangle(contours: np.ndarray, *others: np.ndarray) -> tuple[np.ndarray, ...]:
    """Make every closed polygon of ``contours`` (..., n, 2) simple; apply the same reordering to ``others``.

    Returns (untangled contours, *reordered others), new arrays. ``others`` have the same leading
    shape and n (e.g. the same reconstructions in pixels while ``contours`` are normalised: crossings
    are invariant to a similarity transform). Polygons with NaN are left as they are.
    """
    c = np.array(contours, dtype=np.float64)
    outs = [np.array(o, dtype=np.float64) for o in others]
    lead, n = c.shape[:-2], c.shape[-2]
    flat = c.reshape(-1, n, 2)
    flat_others = [o.reshape(-1, n, o.shape[-1]) for o in outs]
    for r in np.flatnonzero(self_intersecting(flat)):
        order = untangle_order(flat[r])
        flat[r] = flat[r][order]
        for o in flat_others:
            o[r] = o[r][order]
    return (flat.reshape(c.shape), *[fo.reshape(o.shape) for fo, o in zip(flat_others, outs)])
