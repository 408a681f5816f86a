"""People on the floor: a visual-hull occupancy grid over the floor plane, combining every camera's mask.

The floor searched (the rig's workspace plus a margin, or for ``silpose infer --videos`` wherever 2 cameras
see a person, :func:`capture_bounds`) is cut into square cells. For each cell a short vertical
column at the cell's centre, at torso heights (:data:`COLUMN_HEIGHTS`, 0.9-1.3 m: between the hips and
the shoulders of a 1.5-2.0 m person, where the body is solid from every side, unlike the legs during
the stride), is projected into every camera once, at construction. Per frame, a cell's occupancy is the
fraction of its column's points that fall on foreground, and the cell's score is the smallest of those
fractions over the cameras that see the whole column and have a non-empty mask (a person is
foreground in every camera that sees them; a camera whose mask is empty that frame, all-black, says
nothing). Cells seen by fewer than ``min_views`` such cameras score 0.

Where the rays through different people cross, a cell scores like a person too (a ghost): the pipeline keeps
only the peaks that explain foreground the others do not (:mod:`.ghosts`). People are the peaks of the score map
smoothed by a Gaussian (sigma 2 cells), at least
``min_score`` high and ``separation`` metres apart (strongest first), each placed at the score-weighted
centroid of its cells within 0.25 m (sub-cell). A person hidden from one camera (a pillar, a table, a
segmentation that lost them) scores 0 there; so a second, tolerant map takes, where ``min_views + 2`` or
more cameras see a cell, the second-smallest fraction (all cameras but one agree, and still at least
``min_views + 1`` of them: two cameras alone make ghosts wherever their rays cross), and its peaks are
added when no peak of the strict map lies within ``separation``. Measured on the lab recording with the right half of
cam2's masks blanked: the strict map alone lost a person in 68 of 75 frames, strict + tolerant found both
in all 75 (2.9 cm from the pelvis on average); without the blanking the tolerant peaks add nothing (the
tolerant map alone merges the two people in 4 frames of the crossing, which is why it only supplements).

Why a visual hull and not the blobs' foot points through each camera's floor homography: measured on
the lab recording (two walkers crossing three times in front of four cameras on one wall, 150 frames,
lossy mask videos; ``benchmarks/recordings.py``, rows ``floor``), the occupancy grid found both people in
every frame (300 of 300 person-frames, no false detection) 2.6 cm from the true pelvis on average (13.9 cm
at worst); foot points found 93 % of them, 17.4 cm off on average. Foot points need a blob per person and
camera, which a crossing takes away -- merged blobs give one foot point for two people -- and the lowest
silhouette pixel is the front of the nearer foot, up to half a stride and a foot from the body's axis; a
visual hull uses merged blobs as they are (both people are foreground) and the torso column is centred on
the body. Its cost, ~1-4 ms per frame here, is a gather of 5 pixels per cell and camera.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from silpose.shared.rig_frame import PERSON_HEIGHT_M

from ..rig.workspace import MIN_PERSON_FRACTION, project_fast

#: heights (m) of the column sampled above each floor cell: the torso of a 1.5-2.0 m person
COLUMN_HEIGHTS = (0.9, 1.0, 1.1, 1.2, 1.3)
#: floor cell side, metres
CELL_M = 0.05
#: metres of floor searched around the workspace
MARGIN_M = 0.5
#: cells around an occupancy map's non-zero cells that :meth:`FloorGrid.detect` smooths and searches: twice the
#: reach of its Gaussian (sigma 2 cells, OpenCV's kernel of 17 cells) and its 5 x 5 peak test, with a cell to spare
SEARCH_MARGIN_CELLS = 20


def person_reach(cam, person_height: float = PERSON_HEIGHT_M, fraction: float = MIN_PERSON_FRACTION) -> float:
    """Metres: the depth up to which a ``person_height`` person is at least ``fraction`` of ``cam``'s image height
    (``fy h / (fraction H)``; the criterion of ``silpose rig import``'s automatic workspace)."""
    return float(cam.K[1, 1] * person_height / (fraction * cam.height))


def capture_bounds(cameras, bounds, margin: float = MARGIN_M, min_views: int = 2, coarse: float = 0.25):
    """((x_min, x_max), (y_min, y_max)) metres: the floor ``silpose infer --videos`` searches -- the workspace
    ``bounds`` grown by ``margin``, and every floor spot where ``min_views`` cameras see a person's torso column
    (:data:`COLUMN_HEIGHTS`) with the person at least :data:`MIN_PERSON_FRACTION` of the image tall
    (:func:`person_reach`), found on a ``coarse`` grid and grown by one coarse cell.

    Why not the workspace: an imported rig's workspace is where a person is whole in every camera (or in
    ``--min-views`` of them), which on rigs whose cameras each see part of the room (a dome, cameras on
    several walls) is a small square, while people stand anywhere the cameras look. The occupancy grid
    needs ``min_views`` cameras per cell anyway (:class:`FloorGrid`, which searches the same cells).
    """
    (x0, x1), (y0, y1) = bounds
    lo, hi = np.array([x0 - margin, y0 - margin]), np.array([x1 + margin, y1 + margin])
    cams = list(cameras)
    reach = np.array([person_reach(c) for c in cams])
    centres = np.array([np.asarray(c.center, float)[:2] for c in cams]).reshape(-1, 2)
    a, b = (centres - reach[:, None]).min(axis=0), (centres + reach[:, None]).max(axis=0)
    xs, ys = np.arange(a[0], b[0] + coarse, coarse), np.arange(a[1], b[1] + coarse, coarse)
    X, Y = np.meshgrid(xs, ys)
    views = np.zeros(X.size, int)
    for cam, r in zip(cams, reach):
        views += sees_columns(cam, np.stack([X.ravel(), Y.ravel()], 1), r)
    ok = views >= min_views
    if ok.any():
        pts = np.stack([X.ravel()[ok], Y.ravel()[ok]], 1)
        lo, hi = np.minimum(lo, pts.min(axis=0) - coarse), np.maximum(hi, pts.max(axis=0) + coarse)
    return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))


def sees_columns(cam, xy: np.ndarray, reach: float = np.inf, heights=COLUMN_HEIGHTS) -> np.ndarray:
    """(N,) bool: ``cam`` sees the torso column above each floor point ``xy`` (N, 2) metres whole (every height in
    front of it, every pixel, rounded, inside its image) and nearer than ``reach`` metres."""
    hz = np.asarray(heights, float)
    pts = np.concatenate([np.repeat(xy[:, None, :], len(hz), 1), np.broadcast_to(hz[None, :, None], (len(xy), len(hz), 1))], 2)
    depth = cam.to_camera(pts.reshape(-1, 3))[:, 2].reshape(len(xy), len(hz))
    px = np.round(project_fast(cam, pts.reshape(-1, 3))).reshape(len(xy), len(hz), 2)
    return np.all((depth > 0) & (depth <= reach) & cam.in_image(px, margin=0.5), axis=1)


@dataclass(frozen=True)
class Detections:
    """People found on the floor in one frame: positions (D, 2) metres (silpose's x, y), scores (D,) in [0, 1]."""

    positions: np.ndarray
    scores: np.ndarray


class FloorGrid:
    """The occupancy grid of a rig over its workspace (module docstring).

    Args:
        cameras: the rig's cameras (``Camera``), in the order masks are given.
        bounds: ((x_min, x_max), (y_min, y_max)) metres of the workspace; the grid adds ``margin``.
        cell, margin: metres. min_views: cameras that must see a cell.
        search: ((x_min, x_max), (y_min, y_max)) metres, a larger floor to search (:func:`capture_bounds`,
            ``silpose infer --videos``): the grid spans it too, and there, beyond the workspace plus ``margin``,
            a camera sees only cells nearer than :func:`person_reach`.
    Attributes:
        xs (nx,), ys (ny,): cell centres, metres.
        workspace: ((x_min, x_max), (y_min, y_max)) metres, ``bounds`` (:meth:`in_workspace`).
    """

    def __init__(self, cameras, bounds, cell: float = CELL_M, margin: float = MARGIN_M, min_views: int = 2,
                 heights=COLUMN_HEIGHTS, search=None):
        (x0, x1), (y0, y1) = bounds
        self.workspace = ((float(x0), float(x1)), (float(y0), float(y1)))
        x0, x1, y0, y1 = x0 - margin, x1 + margin, y0 - margin, y1 + margin
        (sx0, sx1), (sy0, sy1) = search if search is not None else ((x0, x1), (y0, y1))
        self.cell = float(cell)
        self.xs = x0 + cell * np.arange(np.floor((min(sx0, x0) - x0) / cell), np.floor((max(sx1, x1) - x0) / cell + 1e-9) + 1)
        self.ys = y0 + cell * np.arange(np.floor((min(sy0, y0) - y0) / cell), np.floor((max(sy1, y1) - y0) / cell + 1e-9) + 1)
        self.min_views = int(min_views)
        X, Y = np.meshgrid(self.xs, self.ys, indexing="xy")  # (ny, nx)
        self.X, self.Y = X, Y
        beyond = ((X < x0 - 1e-9) | (X > x1 + 1e-9) | (Y < y0 - 1e-9) | (Y > y1 + 1e-9)).reshape(-1, 1)
        hz = np.asarray(heights, float)
        pts = np.stack([np.repeat(X[..., None], len(hz), -1), np.repeat(Y[..., None], len(hz), -1),
                        np.broadcast_to(hz, X.shape + (len(hz),))], axis=-1).reshape(-1, len(hz), 3)  # (cells, h, 3)
        sees, pixels = [], []
        for cam in cameras:
            depth = cam.to_camera(pts)[..., 2]
            px = np.round(project_fast(cam, pts.reshape(-1, 3)).reshape(pts.shape[:-1] + (2,)))  # cam.project's pixels
            near = ~beyond | (depth <= person_reach(cam))
            sees.append(np.all((depth > 0) & near & cam.in_image(px, margin=0.5), axis=-1))
            pixels.append(px)
        # only the cells min_views cameras see are ever gathered (the others score 0): the search area may be
        # much larger than the workspace
        self.active = np.flatnonzero(np.sum(sees, axis=0) >= self.min_views) if sees else np.zeros(0, np.intp)
        self.index, self.sees = [], []
        for cam, seen, px in zip(cameras, sees, pixels):
            # a point far beyond a distorted lens projects to NaN or to huge pixels: any value outside the image
            # is clipped to its border below (``seen`` is False there), so cap it before the integer cast
            px = np.clip(np.nan_to_num(px[self.active], nan=-1.0, posinf=-1.0, neginf=-1.0), -1,
                         max(cam.width, cam.height)).astype(np.int64)
            flat = np.clip(px[..., 1], 0, cam.height - 1) * cam.width + np.clip(px[..., 0], 0, cam.width - 1)
            self.index.append(np.ascontiguousarray(flat.reshape(-1, len(hz)).T, dtype=np.intp))  # (h, active cells)
            self.sees.append(seen[self.active])
        self.n_heights = len(hz)

    def in_workspace(self, xy: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(N,) bool: floor points ``xy`` (N, 2) metres in the workspace, where the rig films its subjects, grown
        by ``margin`` metres on every side."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        (x0, x1), (y0, y1) = self.workspace
        m = float(margin)
        return (xy[:, 0] >= x0 - m) & (xy[:, 0] <= x1 + m) & (xy[:, 1] >= y0 - m) & (xy[:, 1] <= y1 + m)

    def occupancy(self, masks: list) -> tuple[np.ndarray, np.ndarray]:
        """(strict, tolerant) (ny, nx) float32 scores (module docstring) from per-camera (H, W) {0, 1} uint8
        masks (None: no mask)."""
        ny, nx = self.X.shape
        unseen = np.uint8(255)
        best = np.full(len(self.active), unseen, np.uint8)
        second = best.copy()
        views = np.zeros(len(self.active), np.int16)
        for k, m in enumerate(masks):
            if m is None:
                continue
            flat = m.reshape(-1)
            count = flat[self.index[k][0]].copy()  # foreground points of each column, one height at a time
            for row in self.index[k][1:]:
                count += flat[row]
            count = np.where(self.sees[k], count, unseen)
            np.minimum(second, np.maximum(best, count), out=second)
            np.minimum(best, count, out=best)
            views += self.sees[k]
        strict = best.astype(np.float32) / self.n_heights
        tolerant = np.where(views >= self.min_views + 2, second, best).astype(np.float32) / self.n_heights
        off = (views < self.min_views) | (best == unseen)
        strict[off] = 0.0
        tolerant[off] = 0.0
        maps = np.zeros((2, ny * nx), np.float32)
        maps[0, self.active], maps[1, self.active] = strict, tolerant
        return maps[0].reshape(ny, nx), maps[1].reshape(ny, nx)

    def locate(self, masks: list, min_score: float = 0.7, separation: float = 0.5) -> Detections:
        """People on the floor from per-camera masks: the strict map's peaks plus the tolerant map's peaks
        away from them (module docstring)."""
        strict, tolerant = self.occupancy(masks)
        a = self.detect(strict, min_score, separation)
        b = self.detect(tolerant, min_score, separation)
        if not len(b.positions):
            return a
        if len(a.positions):
            far = np.linalg.norm(b.positions[:, None] - a.positions[None], axis=2).min(axis=1) >= separation
        else:
            far = np.ones(len(b.positions), bool)
        return Detections(np.concatenate([a.positions, b.positions[far]]), np.concatenate([a.scores, b.scores[far]]))

    def detect(self, occupancy: np.ndarray, min_score: float = 0.7, separation: float = 0.5) -> Detections:
        """People in an occupancy map (module docstring).

        The map is smoothed and searched for peaks only on the box of its non-zero cells grown by
        :data:`SEARCH_MARGIN_CELLS` (a few people cover a few per cent of the floor searched): beyond the
        Gaussian's reach (8 cells) the smoothed map is 0, below any ``min_score``, and the box's own border
        reflects only zeros onto cells within reach, so the peaks are those of the whole map."""
        occ = occupancy.astype(np.float32)
        rows, cols = np.flatnonzero(occ.any(axis=1)), np.flatnonzero(occ.any(axis=0))
        if not rows.size:
            return Detections(np.zeros((0, 2)), np.zeros(0))
        m = SEARCH_MARGIN_CELLS
        y0, x0 = max(rows[0] - m, 0), max(cols[0] - m, 0)
        box = np.s_[y0: rows[-1] + m + 1, x0: cols[-1] + m + 1]
        smooth = np.zeros(occ.shape, np.float32)
        smooth[box] = cv2.GaussianBlur(np.ascontiguousarray(occ[box]), (0, 0), 2.0)
        part = smooth[box]
        peak = (part >= cv2.dilate(part, np.ones((5, 5), np.uint8))) & (part >= min_score)
        rows, cols = np.nonzero(peak)
        rows, cols = rows + y0, cols + x0
        order = np.argsort(-smooth[rows, cols], kind="stable")
        kept: list[np.ndarray] = []
        scores = []
        for i in order:
            p = np.array([self.xs[cols[i]], self.ys[rows[i]]])
            if all(np.hypot(*(p - q)) >= separation for q in kept):
                kept.append(p)
                scores.append(float(smooth[rows[i], cols[i]]))
        out = []
        r = int(np.ceil(0.25 / self.cell)) + 1  # the cells within 0.25 m of a peak lie in this window
        for p in kept:
            i, j = int(round((p[1] - self.ys[0]) / self.cell)), int(round((p[0] - self.xs[0]) / self.cell))
            win = np.s_[max(0, i - r): i + r + 1, max(0, j - r): j + r + 1]
            X, Y, occ = self.X[win], self.Y[win], occupancy[win]
            near = ((X - p[0]) ** 2 + (Y - p[1]) ** 2 <= 0.25**2) & (occ > 0.5)
            w = occ * near
            total = float(w.sum())
            out.append([(w * X).sum() / total, (w * Y).sum() / total] if total > 0 else p)
        return Detections(np.asarray(out, float).reshape(-1, 2), np.asarray(scores, float))
