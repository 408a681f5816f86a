"""Joints fitted to the silhouettes they were inferred from: each joint moved, as little as its posterior allows,
to project inside the person's outline in every view used.

The model's answer is a posterior mean of joints given the contours (``silpose.model``); nothing in it says that
a joint must lie *inside* the body, so a wrist or an ankle whose pose the prior rounds off lands a few centimetres
beside the arm or the foot the cameras saw, and the root placed from the contours' centroids
(:mod:`.placement`) carries every joint with it. The views say more: the body, joints included, lies inside every
silhouette that holds the person alone (the views used, ``VIEW_OK``).

:func:`fit_to_silhouettes` takes that as a likelihood. For joint j at X (metres) and used view k with outline
polygon P_k (px, the observed contour the model was given), let ``s_k(X)`` be the signed distance of the projection
``pi_k(X)`` to P_k (positive outside, the nearest point of the outline at distance |s|) and ``m_k`` a margin
(:data:`MARGIN_M` at the joint's depth, px): the joint should lie at least that far inside. Each joint is moved
to the minimum of

    E(X) = sum_k max(s_k(X) + m_k, 0)^2 / sigma_px^2 + (X - X0)^T D^-1 (X - X0),

X0 the placed answer and D = diag(std^2) its posterior variance per axis (the model's ``joint_std``, at least
:data:`MIN_STD_M`): a Gaussian prior times a one-sided Gaussian likelihood of the outline. Joints already inside
every outline by the margin do not move. Levenberg-Marquardt (Nocedal & Wright, *Numerical Optimization*, 2nd ed.,
sec. 10.3; Marquardt's scaling of the damping by the Hessian's diagonal), every joint of every row at once, at most
:data:`N_STEPS` evaluations of E: the Gauss-Newton Hessian and gradient from the residual's gradient ``u_k^T J_k``
(u_k the outward unit normal at the nearest outline point, found among :data:`WINDOW` edges either side of where
it was last -- first from the nearest vertex, and among every edge after a move beyond :data:`REACH` of the
window; J_k the projection's 2 x 3 Jacobian by finite differences). A step that would raise a joint's E is
refused and that joint's damping raised (x :data:`DAMPING_UP`, at least :data:`DAMPING_FIRST`), an accepted step
lowers it (/ :data:`DAMPING_DOWN`); a joint stops once an accepted step is below :data:`SETTLED_M` or its damping
reaches :data:`DAMPING_MAX`. The one-sided residual is what makes damping pay: a Gauss-Newton step sees only the
views a joint is outside of, so it often carries the joint out of another view's outline, and the full step is
refused. An earlier version halved refused steps (at most twice, 3 steps) and stopped a joint whose third try
failed: on Pose2Sim's demos (a 1,200-sample model of their rig) it left 0.921 / 0.901 of the joints inside (2 px)
where this fit, with at most 10 steps tried per joint (the old one: 9), leaves 0.980 / 0.969 (halving 6 times over
10 steps, up to 71 tries: 0.978 / 0.962, twice the time). On the synthetic lab recordings of the table below, whose model
places the joints well, the two agree (joints inside the clean silhouettes, world / relative error: four walkers
crossing 0.938 / 12.01 / 10.03 cm both; apart 0.994 / 8.56 / 6.88 both; two walkers 0.9998 vs 0.9999, 4.27 /
3.72 both; a model of 2,000 lab-rig walkers trained anew, 200 and 150 frames); the run's place stage (placement and
fit) took 0.22 s per 200 steps of four walkers against 0.20. Without the refusal, a step that carried a joint past the margin of every view left only the prior, whose full step took it back where it
started, and joints went back and forth (up to 22 cm apart after 3 and after 6 steps on the lab recording); keeping
a view's residual once it had been positive instead held joints at the margin of views they had since passed.
Joints are fitted independently: a bone's length may change
by the centimetres a joint moves.

Measured on the synthetic lab recordings (:mod:`silpose.datagen.lab`, four 644x486 cameras on one wall; a model
trained on 2,000 lab-rig walkers, M 15 q 40), against the same runs without the fit; "inside": the share of the
joints that project inside the walker's own clean silhouette (2 px) in the views each row used; errors: mean
world-frame / root-relative joint error, and the median over rows of the world-frame error, cm:

=====================================================  ==============  =========================================
recording                                              inside          world / relative / median world
=====================================================  ==============  =========================================
four walkers crossing (``benchmarks.identities``),     0.896 -> 0.936  12.11 / 10.00 / 5.27 -> 11.83 / 9.81 / 5.04
mask videos, 200 frames
the same, colour videos against empty-room clips       0.886 -> 0.925  13.09 / 10.75 / 6.16 -> 13.02 / 10.78 / 6.01
two walkers (``benchmarks.recordings``), mask videos,  0.982 -> 1.000  4.42 / 3.77 / 4.15 -> 4.27 / 3.72 / 4.00
150 frames
=====================================================  ==============  =========================================

The price, on the two walkers' mask videos (three alternating pairs of runs, idle 2-core machine): the placement
stage's share of the run's stage time 4.6-5.1 % -> 12.1-12.8 %, about 1 ms of CPU per step of two people (CPU ms
per step 15.67 / 15.10 / 14.35 without, 15.96 / 15.01 / 15.59 with: within the runs' own spread); 21 % of the
joints take part there, the rest settled by :func:`inside_far_from_outline`. A first version searched every edge of
the outline at every step, ran every projection apart and gathered the outlines per step: 2 ms per step (share
18 %). Since, the nearest-edge search is compiled (:mod:`.outline_kernels`, the same answers bit for bit): the fit of
the two walkers' 150 steps (10 chunks) 0.19 -> 0.10 s, of the four walkers' 200 steps 0.23 -> 0.13 s (the calls
replayed, the previous code and this alternating). ``--no-silhouette-fit`` skips the fit.
"""

from __future__ import annotations

import numpy as np

from silpose.shared.skeleton import N_JOINTS, TERMINAL_JOINTS

__all__ = ["MARGIN_M", "SIGMA_PX", "MIN_STD_M", "N_STEPS", "SETTLED_M", "DAMPING_FIRST", "DAMPING_UP",
           "DAMPING_DOWN", "DAMPING_MAX", "WINDOW", "REACH", "joint_margins", "orientations", "signed_distance", "inside_far_from_outline",
           "fit_to_silhouettes"]

#: metres: a joint should lie at least this far inside each outline (about a wrist's radius); the joints at the end
#: of a chain (head top, wrists, toes: ``TERMINAL_JOINTS``) lie at the body's surface and get no margin
MARGIN_M = 0.02
#: px: the outline's spread about the body's edge (segmentation and resampling)
SIGMA_PX = 1.0
#: metres: the least prior standard deviation of a joint per axis
MIN_STD_M = 0.02
#: evaluations of E (steps tried), at most
N_STEPS = 10
#: metres: the steps end once no joint moves this far
SETTLED_M = 5e-4
#: Levenberg-Marquardt damping: the first after a refused step, its factor up after a refusal and down after an
#: acceptance, and the damping at which a joint stops (its steps about 1e-4 of the Gauss-Newton step)
DAMPING_FIRST = 1.0
DAMPING_UP = 4.0
DAMPING_DOWN = 3.0
DAMPING_MAX = 1e4
#: edges searched either side of a joint's last nearest edge (first: the edge from its nearest vertex): a step moves
#: a joint's image a few px, a contour's edges are 2-3 px long at a person's working size
WINDOW = 12
#: a joint whose image moved farther than this share of the window's edges (the outline's longest) since its nearest
#: edge was found is searched on every edge: near the outline the nearest edge can jump across a gap (between the
#: legs) for a small move. Pose2Sim's single-person demo (full HD, a model unsure of the pose: joints moved 15 cm
#: in the median), joints inside the used outlines (2 px): every edge at every step 0.885; 0.5: 0.865; 0.25: 0.881;
#: 0.1: 0.885
REACH = 0.1
_EPS = 1e-4
_STENCIL = np.vstack([np.zeros(3), _EPS * np.eye(3)])  # (4, 3) metres


def joint_margins(n_joints: int = N_JOINTS) -> np.ndarray:
    """(J,) metres: how far inside the outlines each joint should lie (:data:`MARGIN_M`, 0 for terminal joints)."""
    m = np.full(n_joints, MARGIN_M)
    m[[j for j in TERMINAL_JOINTS if j < n_joints]] = 0.0
    return m


def orientations(polygons: np.ndarray) -> np.ndarray:
    """(U,) +1 or -1: the sign of each closed polygon's (U, n, 2) shoelace area (0 for a degenerate one)."""
    x, y = polygons[..., 0], polygons[..., 1]
    return np.sign((x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1))


def signed_distance(points: np.ndarray, polygons: np.ndarray, which: np.ndarray | None = None,
                    around: np.ndarray | None = None, window: int = 0,
                    orientation: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed distance of points to closed, simple polygons, the nearest polygon point and its edge.

    The nearest point of the edges searched (all of them, or with ``around`` only edges ``around - window`` ..
    ``around + window``: where a point that moved a little finds its nearest edge again) and its side: the outward
    normal of its edge, or at a vertex the sum of the two edges' normals (the pseudo-normal: the side it gives is
    exact for the nearest point of a simple polygon). Compiled: :func:`.outline_kernels.nearest_on_outline`.

    Args:
        points: (M, 2) px.
        polygons: (U, n, 2) px, closed outlines (edges i -> i + 1, n - 1 -> 0).
        which: (M,) int, each point's outline in ``polygons`` (None: point i, outline i).
        around: (M,) int edge indices, or None: every edge.
        window: edges searched either side of ``around``.
        orientation: (U,) the outlines' :func:`orientations` when known.
    Returns:
        (s (M,) px, positive outside; nearest (M, 2) px; edge (M,) int, the nearest point's edge).
    """
    from .outline_kernels import nearest_on_outline  # numba: imported when the fit first runs

    pts = np.ascontiguousarray(points, dtype=np.float64)
    poly = np.ascontiguousarray(polygons, dtype=np.float64)
    which = np.arange(len(pts)) if which is None else np.asarray(which)
    orient = orientations(poly) if orientation is None else np.asarray(orientation, dtype=np.float64)
    start = np.full(len(pts), -1, np.int64) if around is None else np.asarray(around, np.int64) % poly.shape[1]
    return nearest_on_outline(pts, poly, np.ascontiguousarray(which, dtype=np.int64), start, int(window),
                              np.ascontiguousarray(orient, dtype=np.float64))


def inside_far_from_outline(points: np.ndarray, polygons: np.ndarray,
                            margin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(B, P) bool: the points (B, P, 2) px lie inside their closed polygon (B, n, 2) px by more than ``margin``
    (B, P) px -- a cheap test that settles most joints without the nearest edge: inside by the even-odd rule, and
    farther than the margin from every edge, since an edge is no nearer than its nearer end less half its length;
    and (B, P) int, each point's nearest vertex (where :func:`signed_distance` looks for the nearest edge)."""
    # relative to each polygon's first vertex, in float32 (a screen: 1e-3 px is far below the margins compared)
    poly = np.asarray(polygons, float)
    origin = poly[:, :1, :]
    a = (poly - origin).astype(np.float32)
    p = (np.asarray(points, float) - origin).astype(np.float32)
    ax, ay = a[:, None, :, 0], a[:, None, :, 1]  # (B, 1, n)
    nxt = np.roll(a, -1, axis=1)
    abx, aby = nxt[:, None, :, 0] - ax, nxt[:, None, :, 1] - ay
    px, py = p[:, :, None, 0], p[:, :, None, 1]  # (B, P, 1)
    apx, apy = px - ax, py - ay  # (B, P, n)
    straddle = (ay > py) != (ay + aby > py)
    right = (apx * aby < apy * abx) ^ (aby < 0)  # the edge crosses the point's row to its right (signed_distance)
    inside = (np.count_nonzero(straddle & right, axis=2) % 2) == 1
    d2 = apx * apx + apy * apy
    vertex = d2.argmin(axis=2)  # (B, P)
    nearest_vertex = np.sqrt(np.take_along_axis(d2, vertex[..., None], axis=2)[..., 0])
    half_edge = 0.5 * np.sqrt(abx * abx + aby * aby).max(axis=2)  # (B, 1)
    return inside & (nearest_vertex - half_edge - 1e-3 > margin), vertex


#: px: a joint within this distance outside an outline counts as inside it (:func:`share_inside`)
INSIDE_TOLERANCE_PX = 2.0


def share_inside(joints: np.ndarray, contours_px: np.ndarray, used: np.ndarray, cameras,
                 tolerance_px: float = INSIDE_TOLERANCE_PX) -> np.ndarray:
    """(R,) the share of each row's (joint, used view) pairs whose joint projects inside the view's outline, or
    at most ``tolerance_px`` outside it: how well the answer agrees with the silhouettes it came from (the
    ``inside`` column of ``joints.csv``). NaN for rows without a used view or without joints.

    Args:
        joints: (R, J, 3) metres, silpose's frame. contours_px: (R, K, n, 2) px, each camera's observed outline.
        used: (R, K) bool. cameras: K cameras (``project``).
    """
    X = np.asarray(joints, float)
    contours = np.asarray(contours_px, float)
    used = np.asarray(used, bool) & np.isfinite(contours).all(axis=(2, 3))
    rows = np.flatnonzero(used.any(axis=1) & np.isfinite(X).all(axis=(1, 2)))
    out = np.full(len(X), np.nan)
    if rows.size == 0:
        return out
    nj = X.shape[1]
    hits = np.zeros(rows.size)
    for k, cam in enumerate(cameras):
        sel = np.flatnonzero(used[rows, k])
        if sel.size == 0:
            continue
        px = cam.project(X[rows[sel]].reshape(-1, 3))
        d, _, _ = signed_distance(np.nan_to_num(px, nan=-1e6), contours[rows[sel], k], np.repeat(np.arange(sel.size), nj))
        ok = np.isfinite(px).all(axis=1) & (d <= tolerance_px)
        hits[sel] += ok.reshape(sel.size, nj).sum(axis=1)
    out[rows] = hits / (nj * used[rows].sum(axis=1))
    return out


def fit_to_silhouettes(joints: np.ndarray, joint_std: np.ndarray, contours_px: np.ndarray, used: np.ndarray,
                       cameras) -> np.ndarray:
    """Joints moved inside the outlines of the views used (module doc).

    Only the joints that are not already inside every used outline by the margin take part
    (:func:`inside_far_from_outline` first, then :func:`signed_distance`); the others keep their place.

    Args:
        joints: (R, J, 3) metres, silpose's frame: the placed answer X0.
        joint_std: (R, J, 3) metres, its posterior standard deviation per axis (NaN: :data:`MIN_STD_M`).
        contours_px: (R, K, n, 2) px, the observed outline of each camera (anything where not used).
        used: (R, K) bool, the views whose outline holds the person alone.
        cameras: K cameras (``project``, ``to_camera``, ``K``).
    Returns:
        (R, J, 3) metres; rows without a used view, or with non-finite joints, unchanged.
    """
    X0 = np.asarray(joints, float)
    out = X0.copy()
    contours = np.asarray(contours_px, float)
    used = np.asarray(used, bool) & np.isfinite(contours).all(axis=(2, 3))
    rows = np.flatnonzero(used.any(axis=1) & np.isfinite(X0).all(axis=(1, 2)))
    if rows.size == 0:
        return out
    nj = X0.shape[1]
    margins_m = joint_margins(nj)
    focal = np.array([float(cam.K[0, 0]) for cam in cameras])
    # the joints that take part: outside, or within the margin of, some used outline
    active = np.zeros((rows.size, nj), bool)
    vertex = np.zeros((rows.size, nj, len(cameras)), np.intp)  # each joint's nearest outline vertex per camera
    seen_px = np.zeros((rows.size, nj, len(cameras), 2))  # and where it projected
    for k, cam in enumerate(cameras):
        sel = np.flatnonzero(used[rows, k])
        if sel.size == 0:
            continue
        xs = X0[rows[sel]].reshape(-1, 3)
        depth = cam.to_camera(xs)[:, 2]
        margin = (np.tile(margins_m, sel.size) * focal[k] / np.maximum(depth, 1e-6)).reshape(sel.size, nj)
        seen_px[sel, :, k] = cam.project(xs).reshape(sel.size, nj, 2)
        settled, vertex[sel, :, k] = inside_far_from_outline(seen_px[sel, :, k], contours[rows[sel], k], margin)
        active[sel] |= ~settled | (depth <= 0).reshape(sel.size, nj)
    ar, aj = np.nonzero(active)
    if ar.size == 0:
        return out
    row = rows[ar]  # each taking part: its row of the input and its joint
    x0 = X0[row, aj]  # (A, 3)
    std = np.asarray(joint_std, float)[row, aj]
    var = np.maximum(np.where(np.isfinite(std), std, MIN_STD_M), MIN_STD_M) ** 2

    n_cams = len(cameras)
    table = contours.reshape(-1, *contours.shape[2:])  # (R * K, n, 2): outline of row r, camera k at r * K + k
    orient = np.zeros(len(table))
    used_rows = np.flatnonzero(used.reshape(-1))
    orient[used_rows] = orientations(table[used_rows])
    # per (joint taking part, camera): its nearest edge when last found (first: its nearest vertex's edge), and where
    # it projected then; a joint whose image moved farther than REACH of the window's edges is searched on every edge
    nearest_edge = vertex[ar, aj].reshape(-1).copy()
    found_at = seen_px[ar, aj].reshape(-1, 2).copy()
    reach = np.full(len(table), np.inf)  # px a joint's image may move before the window may miss its nearest edge
    loop = np.concatenate([table[used_rows], table[used_rows, :1]], axis=1)
    reach[used_rows] = REACH * WINDOW * np.sqrt((np.diff(loop, axis=1) ** 2).sum(axis=2)).max(axis=1)

    def linearised(x: np.ndarray, idx: np.ndarray):
        """E (I,), its Gauss-Newton Hessian (I, 3, 3) and half gradient (I, 3), of the joints ``idx`` (I,) of those
        taking part, at x (I, 3); and (their positions, pair ids, nearest edges) to keep when the caller accepts
        x. Each pair's nearest edge is searched :data:`WINDOW` edges either side of the last one (every edge when the
        joint's image moved farther than :data:`REACH` of the window's longest edges since)."""
        d = x - x0[idx]
        v = var[idx]
        energy = (d * d / v).sum(axis=1)
        hess = np.zeros((len(x), 3, 3))
        hess[:, [0, 1, 2], [0, 1, 2]] = 1.0 / v
        grad_half = d / v
        # every (joint, used view) pair at once: projections per camera, then one distance computation
        ats, p0s, jacs, polys, margins, pair_ids = [], [], [], [], [], []
        for k, cam in enumerate(cameras):
            at = np.flatnonzero(used[row[idx], k])
            if at.size == 0:
                continue
            xs = x[at]
            uv = cam.project(xs[:, None, :] + _STENCIL)  # (m, 4, 2): the joint, then a step along each axis
            p0 = uv[:, 0]
            depth = cam.to_camera(xs)[:, 2]
            ats.append(at)
            p0s.append(p0)
            jacs.append(((uv[:, 1:] - p0[:, None]) / _EPS).transpose(0, 2, 1))  # (m, 2, 3) by finite differences
            polys.append(row[idx[at]] * n_cams + k)
            margins.append(np.where(depth > 0, margins_m[aj[idx[at]]] * focal[k] / np.maximum(depth, 1e-6), np.nan))
            pair_ids.append(idx[at] * n_cams + k)
        if not ats:
            return energy, hess, grad_half, (np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0, np.intp),
                                             np.zeros((0, 2)))
        at, p0, jac = np.concatenate(ats), np.concatenate(p0s), np.concatenate(jacs)
        pairs, which = np.concatenate(pair_ids), np.concatenate(polys)
        s, near, edge = signed_distance(p0, table, which, nearest_edge[pairs], WINDOW, orient)
        far = np.flatnonzero(np.linalg.norm(p0 - found_at[pairs], axis=1) > reach[which])
        if far.size:  # moved beyond the window's reach: every edge
            s[far], near[far], edge[far] = signed_distance(p0[far], table, which[far], orientation=orient)
        found = (at, pairs, edge, p0)
        res = (s + np.concatenate(margins)) / SIGMA_PX  # NaN behind the camera
        act = (res > 0) & np.isfinite(res)
        if act.any():
            at, p0, jac, s, near, res = at[act], p0[act], jac[act], s[act], near[act], res[act]
            u = p0 - near
            norm = np.linalg.norm(u, axis=1)
            u = np.where(norm[:, None] > 1e-9, u / np.maximum(norm, 1e-12)[:, None], 0.0)
            u = np.where((s < 0)[:, None], -u, u)  # outward normal: from an inside point towards the outline
            gk = np.einsum("mi,mij->mj", u, jac) / SIGMA_PX  # (m, 3): d res / d X
            np.add.at(energy, at, res * res)
            np.add.at(hess, at, gk[:, :, None] * gk[:, None, :])
            np.add.at(grad_half, at, res[:, None] * gk)
        return energy, hess, grad_half, found

    def keep_edges(found, accepted: np.ndarray) -> None:
        """Remember the nearest edges of the pairs of the accepted joints (positions ``accepted`` (I,) bool)."""
        at, pairs, edge, px = found
        ok = accepted[at]
        nearest_edge[pairs[ok]] = edge[ok]
        found_at[pairs[ok]] = px[ok]

    x = x0.copy()
    every = np.arange(len(x))
    energy, hess, grad_half, found = linearised(x, every)
    keep_edges(found, np.ones(len(x), bool))
    damping = np.zeros(len(x))  # Levenberg-Marquardt's lambda per joint: 0 is a full Gauss-Newton step
    alive = every  # joints still moving
    for _ in range(N_STEPS):
        h = hess[alive]
        step = np.linalg.solve(h + damping[alive, None, None] * (h * np.eye(3)), -grad_half[alive][..., None])[..., 0]
        e, h, g, found = linearised(x[alive] + step, alive)
        ok = e <= energy[alive] * (1 + 1e-12)  # a step that would raise the joint's energy is refused
        keep_edges(found, ok)
        took, refused = alive[ok], alive[~ok]
        x[took] += step[ok]
        energy[took], hess[took], grad_half[took] = e[ok], h[ok], g[ok]
        damping[took] /= DAMPING_DOWN
        damping[refused] = np.maximum(damping[refused] * DAMPING_UP, DAMPING_FIRST)
        # a joint is done once its accepted step is below SETTLED_M, or its steps have shrunk to nothing
        going = ~(ok & (np.abs(step).max(axis=1) < SETTLED_M)) & (damping[alive] < DAMPING_MAX)
        alive = alive[going]
        if alive.size == 0:
            break
    out[row, aj] = x
    return out
