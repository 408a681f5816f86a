"""Compiled loops of the robust repairs (numba): searches whose numpy form pays for every candidate it rules out.

Both searches ask, for every contour point, a question about a window of 2w + 1 candidates on another outline. In
numpy each candidate costs a pass over a (views, n) array whatever the answer, and the window's gathers do not stay
in cache; compiled, a point's candidates are a short loop over values in registers, and the far-point search stops
at the first edge that settles the point.

- :func:`nearest_shifts` is :func:`silpose.model.robust.reindex.index_offsets`'s search: the first nearest of the
  2w + 1 index-shifted reconstructed points, compared by squared distance, the root taken once (the same
  floating-point operations in the same order as the numpy form, so the same offsets and distances bit for bit).
- :func:`near_any_edge` is :func:`silpose.model.robust.excursions.far_points`'s test: is a point within the limit
  of a vertex or an edge of the reconstructed outline within ``reach`` indices of its own (the same vertex margin
  and point-to-segment arithmetic as the numpy form).

Measured on the project's 2-core machine (AMD EPYC, AVX2), 8,000 views of 200 points, w 8: the shift search 0.19 s
in numpy, 0.039 s here. The module imports numba, which takes about a second, so its callers import it when they
first need it; ``cache=True`` keeps the compiled code beside this file (numba's cache, in ``__pycache__``) so that
only the first process on a machine compiles it (about 2 s).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["nearest_shifts", "near_any_edge", "segment_offset", "median_of", "biweight_pseudo"]


@njit(cache=True, nogil=True, inline="always")
def segment_offset(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> tuple[float, float, float]:  # pragma: no cover (compiled)
    """(t, dx, dy): the point ``a + t (b - a)``, t in [0, 1], of the segment a -> b nearest the point p, and the offset
    ``p - (a + t (b - a))`` px (a zero-length segment: its end a)."""
    abx = bx - ax
    aby = by - ay
    apx = px - ax
    apy = py - ay
    t = (apx * abx + apy * aby) / max(abx * abx + aby * aby, 1e-12)
    t = min(max(t, 0.0), 1.0)
    return t, apx - t * abx, apy - t * aby


@njit(cache=True, nogil=True)
def nearest_shifts(observed: np.ndarray, recon: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover (compiled)
    """For every observed point i, the first nearest reconstructed point among indices i - window .. i + window.

    Args:
        observed, recon: (V, n, 2) float64 px, C-contiguous.
        window: half-width in points, 0 < window < n.
    Returns:
        (offsets (V, n) int64, the index difference j - i of the first nearest; distances (V, n) px).
    """
    v, n = observed.shape[0], observed.shape[1]
    width = n + 2 * window
    best_k = np.empty((v, n), dtype=np.int64)
    best_d = np.empty((v, n))
    ox, oy = np.empty(n), np.empty(n)
    rx, ry = np.empty(width), np.empty(width)  # the reconstruction padded cyclically: shift k is [window + k, .. + n)
    d2best = np.empty(n)
    kbest = np.empty(n, dtype=np.int64)
    for a in range(v):
        for i in range(n):
            ox[i] = observed[a, i, 0]
            oy[i] = observed[a, i, 1]
        for i in range(width):
            j = (i - window) % n
            rx[i] = recon[a, j, 0]
            ry[i] = recon[a, j, 1]
        for i in range(n):
            dx = ox[i] - rx[i]
            dy = oy[i] - ry[i]
            d2best[i] = dx * dx + dy * dy
            kbest[i] = -window
        for k in range(-window + 1, window + 1):
            s = window + k
            for i in range(n):  # branch-free, so that the compiler vectorises it
                dx = ox[i] - rx[s + i]
                dy = oy[i] - ry[s + i]
                d2 = dx * dx + dy * dy
                closer = d2 < d2best[i]
                d2best[i] = d2 if closer else d2best[i]
                kbest[i] = k if closer else kbest[i]
        for i in range(n):
            best_k[a, i] = kbest[i]
            best_d[a, i] = np.sqrt(d2best[i])
    return best_k, best_d


@njit(cache=True, nogil=True)
def near_any_edge(points: np.ndarray, polygon: np.ndarray, limit: np.ndarray, views: np.ndarray,
                  index: np.ndarray, reach: int) -> np.ndarray:  # pragma: no cover (compiled)
    """(P,) bool: point ``index`` of view ``views`` (P,) of ``points`` (V, n, 2) px is within ``limit`` (V,) px of a
    vertex or an edge ``j -> j + 1`` of ``polygon`` (V, n, 2), j within ``reach`` of its index (cyclic).

    A vertex within ``limit (1 - 1e-9)`` settles it; otherwise an edge whose point-to-segment distance is at most
    the limit. Candidates are tried from the point's own index outwards, and the first that settles it ends the
    search.
    """
    n = points.shape[1]
    out = np.zeros(views.size, dtype=np.bool_)
    for q in range(views.size):
        a = views[q]
        i = index[q]
        px = points[a, i, 0]
        py = points[a, i, 1]
        lim = limit[a]
        inner = lim * (1.0 - 1e-9)
        inner2 = inner * inner
        # vertices i - reach .. i + reach + 1 (the ends of the edges), nearest indices first
        for step in range(2 * reach + 2):
            k = (step + 1) // 2 if step % 2 else -(step // 2)
            if k > reach + 1 or k < -reach:
                continue
            j = (i + k) % n
            gx = polygon[a, j, 0] - px
            gy = polygon[a, j, 1] - py
            if gx * gx + gy * gy <= inner2:
                out[q] = True
                break
        if out[q]:
            continue
        for step in range(2 * reach + 1):
            k = (step + 1) // 2 if step % 2 else -(step // 2)
            j = (i + k) % n
            e = (j + 1) % n
            _, dx, dy = segment_offset(px, py, polygon[a, j, 0], polygon[a, j, 1], polygon[a, e, 0], polygon[a, e, 1])
            if np.sqrt(dx * dx + dy * dy) <= lim:
                out[q] = True
                break
    return out


@njit(cache=True, nogil=True)
def _select(buf: np.ndarray, k: int) -> None:  # pragma: no cover (compiled)
    """Reorder ``buf`` (n,) so that ``buf[k]`` is its k-th smallest value, the values before it not larger and those
    after it not smaller (Hoare's selection with a median-of-three pivot; no NaN in ``buf``)."""
    lo, hi = 0, buf.size - 1
    while hi > lo:
        mid = (lo + hi) >> 1
        a, b, c = buf[lo], buf[mid], buf[hi]
        if a < b:
            pivot = b if b < c else (c if a < c else a)
        else:
            pivot = a if a < c else (c if b < c else b)
        i, j = lo, hi
        while i <= j:
            while buf[i] < pivot:
                i += 1
            while buf[j] > pivot:
                j -= 1
            if i <= j:
                t = buf[i]
                buf[i] = buf[j]
                buf[j] = t
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return


@njit(cache=True, nogil=True)
def median_of(buf: np.ndarray) -> float:  # pragma: no cover (compiled)
    """``np.median`` of ``buf`` (n,) float64, reordering it: NaN when it holds a NaN, else its middle value, or the
    mean ``(a + b) / 2`` of its two middle values for even n (the same order statistics and arithmetic, so the same
    value bit for bit)."""
    n = buf.size
    for i in range(n):
        if np.isnan(buf[i]):
            return np.nan
    k = n // 2
    if n % 2:
        _select(buf, k)
        return buf[k]
    _select(buf, k - 1)
    upper = buf[k]
    for i in range(k + 1, n):
        if buf[i] < upper:
            upper = buf[i]
    return (buf[k - 1] + upper) / 2.0


@njit(cache=True, nogil=True)
def biweight_pseudo(observed: np.ndarray, recon: np.ndarray, present: np.ndarray, threshold: float,
                    scale_floor_px: float) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover (compiled)
    """A reweighting pass's point weights and pseudo-observation with index correspondences, view by view.

    Per observed view: residuals ``r_i = |o_i - c_i|`` px, Tukey's biweights ``u_i = (1 - z_i^2)^2`` for
    ``z_i = r_i / (threshold max(1.4826 median(r) + scale_floor_px, 1e-12)) < 1``, else 0, and 0 where not finite
    (every point of a view holding a NaN); pseudo-observation ``c_i + u_i (o_i - c_i)``. Absent views: weights 0,
    the observed contour. :func:`silpose.model.robust.weights.point_weights` and
    :func:`silpose.model.robust.loop.pseudo_observation` of the same arrays, bit for bit.

    Args:
        observed, recon: (N, K, n, 2) float64 px.
        present: (N, K) bool.
    Returns:
        (weights (N, K, n), pseudo-observations (N, K, n, 2) px).
    """
    f, k, n = observed.shape[0], observed.shape[1], observed.shape[2]
    u = np.zeros((f, k, n))
    pseudo = np.empty(observed.shape)
    r = np.empty(n)
    buf = np.empty(n)
    for a in range(f):
        for v in range(k):
            if not present[a, v]:
                for i in range(n):
                    pseudo[a, v, i, 0] = observed[a, v, i, 0]
                    pseudo[a, v, i, 1] = observed[a, v, i, 1]
                continue
            for i in range(n):
                dx = observed[a, v, i, 0] - recon[a, v, i, 0]
                dy = observed[a, v, i, 1] - recon[a, v, i, 1]
                r[i] = np.sqrt(dx * dx + dy * dy)
                buf[i] = r[i]
            med = median_of(buf)
            s = 1.4826 * med + scale_floor_px
            if s < 1e-12:
                s = 1e-12
            scale = threshold * s
            for i in range(n):
                z = r[i] / scale
                w = 0.0
                if z < 1.0:
                    w = (1.0 - z * z) * (1.0 - z * z)
                if not np.isfinite(w):
                    w = 0.0
                u[a, v, i] = w
                for c in range(2):
                    pseudo[a, v, i, c] = (observed[a, v, i, c] - recon[a, v, i, c]) * w + recon[a, v, i, c]
    return u, pseudo
