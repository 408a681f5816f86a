"""Excursions: stretches of an outline that leave the body and come back (shadows, blobs, bitten holes).

A shadow at the feet or a blob stuck to an arm adds a loop to the silhouette's outline: the contour
walks out along the extra region and returns near where it left. Besides moving those points, the loop
lengthens the outline, so arc-length resampling (docs/conventions.md, "Contours") shifts the index of
every point after it -- robust per-point weights (``silpose.model.robust``) down-weight the loop but
cannot undo the shift. A hole biting into the outline does the same inwards.

:func:`trim_excursions` finds such loops against a reconstruction of the contour and replaces them by
their chord, re-spacing the points by index. A *run* is a maximal cyclic stretch of points farther than
``threshold`` from the reconstructed outline (point-to-polygon distance, so an index shift alone does not
make a run); with ``a``, ``b`` the inlier points either side of it, the run is an excursion when

    arc(a -> run -> b) > ratio * |b - a|,     arc - |b - a| > extra,     (len(run) + 1) - span_rec >= 2,

i.e. it goes out and comes back (a displaced stretch of outline keeps arc ~ chord) and it *added* points:
``span_rec`` is the number of reconstructed points between the vertices nearest ``a`` and ``b`` (points
moved in place, without lengthening the outline, keep their indices and are left to the robust weights).
The excursion's points are replaced by ``span_rec - 1`` points on the chord ``a -> b``, and the sequence is
resampled to n points *by index* (not arc length, which jittered inputs would distort), from the original
start point. ``threshold`` and ``extra`` are in units of the view's scale (RMS distance of its points from
their centroid, about 36 px on the default preset).

Chosen on the held-out part of the default preset's training split (200 walkers, 4 views, robust
inference, M 15 q 40 model; mean pose error cm without -> with 2 passes of threshold 6/36, ratio 4, extra
15/36): clean 2.85 -> 2.86, standard noise 3.79 -> 3.77, "mask mild" 6.10 -> 5.67, "mask strong"
17.29 -> 15.23. Tried: without the ``span_rec`` test and with as many chord points as the reconstruction's
spacing fits, "mask mild" 5.47 but 4 % of standard-noise views trimmed in error; ratio 2.5-3 or a lower
threshold, "mask mild" 5.4-5.8 at up to +0.07 cm on the standard noise; growing runs while their
neighbours are off the outline (2/36), worse everywhere (standard 4.02); arc-length instead of index
resampling of the trimmed outline, standard noise 5 cm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .observed_views import observed_views

__all__ = ["ExcursionSettings", "point_to_polygon_distance", "far_points", "excursion_candidates", "excursion_runs",
           "outline_lengths", "run_arcs", "trim_excursions"]

#: views per block of :func:`point_to_polygon_distance` (a block holds n x m x 2 floats per view)
_BLOCK_VIEWS = 32


@dataclass(frozen=True)
class ExcursionSettings:
    """Thresholds of :func:`trim_excursions` (module doc); ``threshold`` and ``extra`` in view scales."""

    threshold: float = 6.0 / 36.0
    ratio: float = 4.0
    extra: float = 15.0 / 36.0

    def __post_init__(self) -> None:
        for name in ("threshold", "ratio", "extra"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"excursion {name} must be finite and > 0, got {v!r}")


def point_to_polygon_distance(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """(..., n) distance of every point (..., n, 2) to the closed polygon (..., m, 2) through its vertices
    (all m edges; O(n m) per contour)."""
    p = np.asarray(points, dtype=np.float64)
    a = np.asarray(polygon, dtype=np.float64)
    lead = p.shape[:-2]
    p = p.reshape(-1, *p.shape[-2:])
    a = a.reshape(-1, *a.shape[-2:])
    out = np.empty(p.shape[:2])
    for s in range(0, len(p), _BLOCK_VIEWS):
        pp, aa = p[s:s + _BLOCK_VIEWS], a[s:s + _BLOCK_VIEWS]
        out[s:s + _BLOCK_VIEWS] = _segment_distance(pp[:, :, None, :], aa[:, None, :, :],
                                                    np.roll(aa, -1, axis=1)[:, None, :, :]).min(axis=2)
    return out.reshape(*lead, p.shape[1])


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (broadcast shape) of points ``p`` (..., 2) to the segments ``a -> b`` (..., 2)."""
    abx, aby = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    apx, apy = p[..., 0] - a[..., 0], p[..., 1] - a[..., 1]  # coordinates apart: no reductions over an axis of 2
    t = np.clip((apx * abx + apy * aby) / np.maximum(abx * abx + aby * aby, 1e-12), 0.0, 1.0)
    dx, dy = apx - t * abx, apy - t * aby
    return np.sqrt(dx * dx + dy * dy)


def far_points(points: np.ndarray, polygon: np.ndarray, limit: np.ndarray,
               extra: np.ndarray | None = None) -> np.ndarray:
    """(V, n) bool: points (V, n, 2) farther than ``limit`` (V,) px from the closed polygon (V, n, 2).

    Only points farther than the limit from their index-corresponding vertex can be (the distance to the
    polygon is at most that); for those, the edges within ``n // 4`` indices are searched (an index shift of
    a quarter of the outline is beyond any excursion we trim; a point whose nearest edge is farther along
    counts as far, which can only lengthen a run that is already one): a point is far when every one of those
    edges is farther than the limit (the point-to-segment distance of :func:`_segment_distance`). The search is
    compiled (:func:`silpose.model.robust.kernels.near_any_edge`): a vertex within the limit settles a point first,
    then the edges from the point's own index outwards, and the first within the limit ends it.

    ``extra`` (V,) px: only the far points that may belong to an excursion are wanted, that is to a run whose
    ``arc - chord`` exceeds ``extra`` (module doc); before the search, the points in question that lie in a run of
    such points (:func:`excursion_candidates`) too short to exceed it are left out (reported not far), and after it
    the far runs that do not exceed it. The far runs reported are then exactly those whose ``arc - chord``
    exceeds ``extra`` (to a margin for rounding), and every point of a view that is far all round.
    """
    from .kernels import near_any_edge  # numba: imported on first use (module doc of .kernels)

    v, n = points.shape[:2]
    limit = np.asarray(limit, dtype=np.float64)
    ex, ey = points[..., 0] - polygon[..., 0], points[..., 1] - polygon[..., 1]  # coordinates apart (module note)
    maybe = np.sqrt(ex * ex + ey * ey) > limit[:, None]
    far = np.zeros((v, n), dtype=bool)
    views, idx = np.nonzero(maybe)
    cum = None if extra is None or views.size == 0 else outline_lengths(points)
    if cum is not None:
        views, idx = excursion_candidates(points, cum, views, idx, np.asarray(extra, dtype=np.float64))
    if views.size:
        pts, poly = np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(polygon, dtype=np.float64)
        within = near_any_edge(pts, poly, np.ascontiguousarray(limit), views.astype(np.int64), idx.astype(np.int64),
                               max(n // 4, 1))
        views, idx = views[~within], idx[~within]
    if cum is not None:  # the far runs themselves
        views, idx = excursion_candidates(points, cum, views, idx, np.asarray(extra, dtype=np.float64))
    far[views, idx] = True
    return far


def outline_lengths(points: np.ndarray) -> np.ndarray:
    """(V, n + 1) px: the cumulative edge lengths of closed outlines (V, n, 2), entry i the length from point 0 to
    point i along the outline (entry n: the whole perimeter)."""
    lx = np.roll(points[..., 0], -1, axis=1) - points[..., 0]
    ly = np.roll(points[..., 1], -1, axis=1) - points[..., 1]
    cum = np.zeros((points.shape[0], points.shape[1] + 1))
    np.cumsum(np.sqrt(lx * lx + ly * ly), axis=1, out=cum[:, 1:])
    return cum


def excursion_candidates(points: np.ndarray, cum: np.ndarray, views: np.ndarray, idx: np.ndarray,
                         extra: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points ``(views, idx)`` (P,) of ``points`` (V, n, 2) px, listed by view then index, that lie in a run of
    them (a maximal cyclic stretch of consecutive indices of one view) whose ``arc - chord`` exceeds ``extra`` (V,)
    px of their view, or in a view where they are every point; in their order. ``cum``: the outlines'
    :func:`outline_lengths`.

    Why that is enough (:func:`far_points`): a run of far points lies inside a run of these points (far points are
    among them), and the arc minus the chord of a path cannot exceed that of a longer path around it (triangle
    inequality: each end's extra stretch of arc is at least the chord's change), so a run of far points inside a run
    of these whose ``arc - chord`` does not exceed ``extra`` fails the excursion test ``arc - chord > extra`` too.
    The comparison keeps a margin of 1e-9 (arc + 1) px for the rounding of the cumulative sums."""
    if views.size == 0:
        return views, idx
    n = points.shape[1]
    brk = np.empty(views.size, dtype=bool)  # a run starts here
    brk[0] = True
    np.logical_or(views[1:] != views[:-1], idx[1:] != idx[:-1] + 1, out=brk[1:])
    run = np.cumsum(brk) - 1  # each point's run
    first = np.flatnonzero(brk)
    rv, s = views[first], idx[first]
    length = np.diff(np.r_[first, views.size])
    # a view's last run that ends at n - 1 goes on with its first run when that starts at 0 (cyclic): one run, from
    # the last run's start
    new_view = np.r_[True, rv[1:] != rv[:-1]]
    view_first = np.maximum.accumulate(np.where(new_view, np.arange(rv.size), 0))  # each run's view's first run
    last = np.flatnonzero(np.r_[new_view[1:], True] & (s + length == n))
    fr = view_first[last]
    join = (s[fr] == 0) & (fr != last)
    last, fr = last[join], fr[join]
    length[last] += length[fr]
    a = (s - 1) % n
    e = a + length + 1  # edges a -> first, ..., last -> b: from outline position a to e (mod n)
    e_in = np.minimum(e, n)
    arc = cum[rv, e_in] - cum[rv, a] + np.where(e > n, cum[rv, np.maximum(e - n, 0)], 0.0)
    b = (s + length) % n
    dx, dy = points[rv, b, 0] - points[rv, a, 0], points[rv, b, 1] - points[rv, a, 1]
    chord = np.sqrt(dx * dx + dy * dy)
    drop = (length < n) & (arc - chord + 1e-9 * (arc + 1.0) <= extra[rv])
    drop[fr] = drop[last]  # the first run goes with the last
    if not drop.any():
        return views, idx
    keep = ~drop[run]
    return views[keep], idx[keep]

def excursion_runs(flags: np.ndarray) -> list[np.ndarray]:
    """Maximal cyclic runs of True in the (n,) bool ``flags``, each as its indices in contour order."""
    flags = np.asarray(flags, dtype=bool)
    n = len(flags)
    if not flags.any():
        return []
    if flags.all():
        return [np.arange(n)]
    first_out = int(np.flatnonzero(~flags)[0])
    order = (np.arange(n) + first_out) % n  # start on an inlier so no run wraps
    f = flags[order]
    edges = np.diff(np.r_[0, f.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [order[s:e] for s, e in zip(starts, ends)]


def _nearest_vertex(point: np.ndarray, polygon: np.ndarray, around: int) -> int:
    """Index of the vertex of ``polygon`` (n, 2) nearest ``point`` (2,) within n // 4 indices of ``around``."""
    n = len(polygon)
    j = (around + np.arange(-(n // 4), n // 4 + 1)) % n
    return int(j[np.argmin(np.sum((polygon[j] - point) ** 2, axis=1))])


def _trim_view(pts: np.ndarray, rec: np.ndarray, far: np.ndarray, scale: float,
               settings: ExcursionSettings, starts=None) -> np.ndarray | None:
    """The trimmed (n, 2) contour of one view, or None when it has no excursion (module doc); ``far`` (n,)
    flags the points farther than the threshold from the reconstructed outline; ``starts``: the first indices of
    the only runs that can be excursions (:func:`_candidate_views`), None = every run."""
    n = len(pts)
    drop = np.zeros(n, dtype=bool)
    keep_between: dict[int, int] = {}  # first index of a trimmed run -> points its chord gets
    for run in excursion_runs(far):
        lo, hi = int(run[0]), int(run[-1])
        if starts is not None and lo not in starts:
            continue
        a, b = (lo - 1) % n, (hi + 1) % n
        arc = np.linalg.norm(np.diff(pts[np.r_[a, run, b]], axis=0), axis=1).sum()
        chord = float(np.linalg.norm(pts[b] - pts[a]))
        span_rec = (_nearest_vertex(pts[b], rec, b) - _nearest_vertex(pts[a], rec, a)) % n
        if span_rec > n // 2:
            continue
        inserted = (len(run) + 1) - span_rec  # points the loop added to the outline
        if arc > settings.ratio * chord and arc - chord > settings.extra * scale and inserted >= 2:
            drop[run] = True
            keep_between[int(run[0])] = max(span_rec - 1, 0)
    if not drop.any() or (~drop).sum() <= n // 2:  # nothing found, or too much: leave the view alone
        return None
    # the kept points in order from the first kept one, each trimmed run replaced by the points of its chord, as many
    # as the outline has there (one piece per stretch: the runs of ``drop`` start after a kept point)
    i0 = 0 if not drop[0] else int(np.flatnonzero(~drop)[0])
    order = (np.arange(n) + i0) % n
    pieces: list[np.ndarray] = []
    at = 0
    for r in excursion_runs(drop[order]):
        lo, hi = int(r[0]), int(r[-1])
        pieces.append(pts[order[at:lo]])
        a, b = pts[(order[lo] - 1) % n], pts[(order[hi] + 1) % n]
        m = keep_between[int(order[lo])] + 1
        pieces.append(a + (np.arange(1, m) / m)[:, None] * (b - a))
        at = hi + 1
    pieces.append(pts[order[at:]])
    seq = np.concatenate(pieces)
    path = np.vstack([seq, seq[:1]])
    at = np.arange(n) * ((len(path) - 1) / n)  # index resampling of the closed sequence
    return np.stack([np.interp(at, np.arange(len(path)), path[:, 0]), np.interp(at, np.arange(len(path)), path[:, 1])],
                    axis=1)


def _candidate_views(pts: np.ndarray, rec: np.ndarray, far: np.ndarray, scales: np.ndarray,
                     settings: ExcursionSettings) -> dict:
    """The views (V, n, 2) that may have an excursion, {view index: first indices of its runs that may be one, or
    None for every run}: every run of every view tested at once with :func:`_trim_view`'s criteria, its arc from
    cumulative edge lengths (a margin of 1e-9 covers their rounding; :func:`_trim_view` decides). Views whose far
    points cover the whole outline are candidates (None)."""
    n = far.shape[1]
    whole = far.all(axis=1)
    rv, s, length, arc, chord = run_arcs(pts, far)
    if rv.size == 0:
        return {int(j): None for j in np.flatnonzero(whole)}
    a, b = (s - 1) % n, (s + length) % n
    tol = 1e-9 * (arc + 1.0)
    # the loop tests first; the nearest reconstructed vertices only for the runs that pass them
    ok = (arc + tol > settings.ratio * chord) & (arc - chord + tol > settings.extra * scales[rv])
    sel = np.flatnonzero(ok)
    rv, s, a, b, length = rv[sel], s[sel], a[sel], b[sel], length[sel]
    near = (np.arange(-(n // 4), n // 4 + 1))[None, :]

    def nearest(i):  # _nearest_vertex of pts[rv, i] among rec[rv] within n // 4 of i
        j = (i[:, None] + near) % n
        return j[np.arange(j.shape[0]), np.argmin(np.sum((rec[rv[:, None], j] - pts[rv, i][:, None, :]) ** 2, axis=-1),
                                                  axis=1)]

    span = (nearest(b) - nearest(a)) % n
    ok = (span <= n // 2) & ((length + 1) - span >= 2)
    out: dict = {}
    for j, start in zip(rv[ok].tolist(), s[ok].tolist()):
        out.setdefault(j, set()).add(start)
    out.update({int(j): None for j in np.flatnonzero(whole)})
    return dict(sorted(out.items()))


def run_arcs(pts: np.ndarray, flags: np.ndarray) -> tuple[np.ndarray, ...]:
    """Every maximal cyclic run of True in ``flags`` (V, n) of the views where not all are True, with the outline
    (V, n, 2) px it lies on: (view, first index, length (R,) int; arc, chord (R,) px), ``arc`` the length of the
    path a -> run -> b through the points ``a``, ``b`` either side of the run (from cumulative edge lengths: equal
    to a direct sum to rounding), ``chord`` the distance |b - a|. Runs are listed by view, then first index."""
    v, n = flags.shape
    whole = flags.all(axis=1)
    start = flags & ~np.roll(flags, 1, axis=1) & ~whole[:, None]
    rv, s = np.nonzero(start)
    if rv.size == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, empty, np.zeros(0), np.zeros(0)
    # only the views with a run: their rows, u, in the arrays below (the same arithmetic per view as on all of them)
    used, u = np.unique(rv, return_inverse=True)
    u = u.reshape(-1)
    flags_u, pts_u = flags[used], pts[used]
    # each run's length: to its view's next point that is not flagged (cyclic), from the sorted flat run ends
    ends_v, ends_i = np.nonzero(flags_u & ~np.roll(flags_u, -1, axis=1))
    flat_end = ends_v * n + ends_i
    k = np.searchsorted(flat_end, u * n + s)
    wraps = (k == flat_end.size) | (ends_v[np.minimum(k, flat_end.size - 1)] != u)
    first_end = ends_i[np.searchsorted(flat_end, u * n)]  # the view's first run end (the wrapping run's)
    last = np.where(wraps, first_end + n, ends_i[np.minimum(k, flat_end.size - 1)])
    length = last + 1 - s  # points in the run
    s3 = s + n
    a, b = (s - 1) % n, (s + length) % n
    lx = np.roll(pts_u[..., 0], -1, axis=1) - pts_u[..., 0]
    ly = np.roll(pts_u[..., 1], -1, axis=1) - pts_u[..., 1]
    edges = np.sqrt(lx * lx + ly * ly)  # (U, n) edge i -> i + 1
    cum = np.concatenate([np.zeros((used.size, 1)), np.cumsum(np.tile(edges, 3), axis=1)], axis=1)
    arc = cum[u, s3 + length] - cum[u, s3 - 1]  # edges a -> first, ..., last -> b
    chord = np.linalg.norm(pts[rv, b] - pts[rv, a], axis=-1)
    return rv, s, length, arc, chord


def trim_excursions(contours_px: np.ndarray, recon_px: np.ndarray, present: np.ndarray,
                    settings: ExcursionSettings = ExcursionSettings(),
                    scales: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Replace the excursions of observed contours by their chords (module doc).

    Args:
        contours_px: (N, K, n, 2) observed contours, px (absent views may hold NaN).
        recon_px: (N, K, n, 2) their reconstructions, px.
        present: (N, K) bool, observed views.
        settings: thresholds.
        scales: (N, K) px, the observed contours' normalisation scales when known
            (:func:`~silpose.model.robust.observed_views.observed_views`).
    Returns:
        (contours (N, K, n, 2) float64 with the excursions trimmed, changed (N, K) bool).
    """
    ov = observed_views(contours_px, recon_px, present, scales)
    if ov.rows.size == 0:
        return ov.contours, ov.changed
    # (V, n): the far points that may belong to an excursion (the others cannot change the answer)
    far = far_points(ov.points, ov.recon, settings.threshold * ov.scales, settings.extra * ov.scales)
    for j, starts in _candidate_views(ov.points, ov.recon, far, ov.scales, settings).items():
        trimmed = _trim_view(ov.points[j], ov.recon[j], far[j], float(ov.scales[j]), settings, starts)
        if trimmed is not None:
            ov.set(j, trimmed)
    return ov.contours, ov.changed
