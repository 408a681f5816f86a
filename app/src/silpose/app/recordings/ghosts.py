"""Explaining away: the floor grid's ghosts are dropped when the people found before them explain their evidence.

The occupancy grid (:mod:`.floor`) finds a person wherever every camera that sees a floor cell's torso column sees
foreground there. With several people in the room, the rays through different people cross: a cell whose column
lies on person A's pixels in some cameras and on person B's in the others scores like a person -- a ghost. With
cameras on one wall (the lab rigs) the crossings lie between and behind the people, and each ghost takes a share
of the real people's blobs (their views become "merged") and, when it lasts, an id.

The classic cure of multi-view occupancy (Fleuret et al., "Multicamera People Tracking with a Probabilistic
Occupancy Map", PAMI 2008; greedy "explain the silhouettes" selections) is to explain the masks with as few people
as possible: a candidate is kept only if it explains foreground that the candidates kept before it do not.
:func:`explain_away` does this greedily on the grid's peaks, strongest first (the caller's order; the pipeline
puts first the candidates where a person is predicted, below, then those whose blob ends at their own feet in more
cameras, :func:`.views.grounded`, which a ghost's rarely does, then the grid's score): a kept person explains, in each camera, the image box of the cylinder
of radius :data:`EXPLAIN_RADIUS_M` standing at their floor point (floor to :data:`~.views.BODY_HEIGHT_M`); a
candidate is kept when, in at least ``min_views`` cameras, at least ``min_share`` of its torso column
(:data:`~.floor.COLUMN_HEIGHTS`) falls on foreground that no kept person explains.

A ghost's column lies, in every camera, on a real person's pixels: once they are kept it explains nothing. A real
person hidden behind (or in front of) a kept one in some cameras keeps the cameras where they stand clear. Hidden
in all but one camera -- walkers crossing in front of cameras on one wall -- they would be dropped, so a candidate
may need fewer cameras (``min_views`` per candidate): the pipeline keeps, first and whatever they explain, the
candidates where a person's track seen lately predicts someone (within its gate,
:meth:`.tracking.Tracker.vouched`) -- a ghost that close to a person's predicted position is that person -- and
asks the rest for ``min_views`` cameras. Measured with explaining away on the lab recording (two walkers crossing,
50 frames of lossy mask videos, tests/app/recordings/test_lab.py): 2 of the 100 person-frames lost at the crossing
when every candidate needed 2 cameras, none since. The pipeline explains ghosts away in colour videos, where a
ghost that lasts keeps static clutter from becoming background (:mod:`.pipeline`, "Static clutter"; the measured
cost on mask videos of four walkers is there).
"""

from __future__ import annotations

import numpy as np

from .floor import COLUMN_HEIGHTS
from .views import body_box

__all__ = ["EXPLAIN_RADIUS_M", "explain_away"]

#: metres: radius of the cylinder a kept person explains: half the floor grid's least separation of two people
#: (0.5 m, :meth:`.floor.FloorGrid.locate`), so every pixel it claims is nearer their axis than anyone else's
EXPLAIN_RADIUS_M = 0.25


def explain_away(cameras, masks: list, positions: np.ndarray, order, min_views=2, min_share: float = 0.7,
                 radius: float = EXPLAIN_RADIUS_M) -> np.ndarray:
    """(D,) bool: the candidates kept (module docstring).

    Args:
        cameras: the K cameras the masks are at (``Camera``).
        masks: K (H, W) masks ({0, 1} or {0, 255} uint8), None where a camera has no mask this frame.
        positions: (D, 2) metres, the candidates' floor points.
        order: (D,) candidate indices, strongest first.
        min_views: cameras in which a kept candidate explains foreground of its own: one number, or (D,) one per
            candidate.
        min_share: share of a column's points that must fall on unexplained foreground.
        radius: metres (:data:`EXPLAIN_RADIUS_M`).
    """
    xy = np.asarray(positions, float).reshape(-1, 2)
    D = len(xy)
    keep = np.zeros(D, bool)
    if D == 0:
        return keep
    hz = np.asarray(COLUMN_HEIGHTS, float)
    cols = np.concatenate([np.repeat(xy[:, None], len(hz), 1), np.broadcast_to(hz[None, :, None], (D, len(hz), 1))], -1)
    need = int(np.ceil(min_share * len(hz) - 1e-9))
    views_needed = np.broadcast_to(np.asarray(min_views, int), (D,))
    own_fg, boxes, pts = [], [], []  # per camera: (D, h) column points on foreground (False where unseen), (D, 4)
    for cam, m in zip(cameras, masks):  # boxes, (D, h, 2) column pixels (None: no mask)
        if m is None:
            own_fg.append(np.zeros((D, len(hz)), bool))
            boxes.append(np.full((D, 4), np.nan))
            pts.append(None)
            continue
        px = cam.project(cols)  # (D, h, 2)
        pts.append(px)
        seen = np.all((cam.to_camera(cols)[..., 2] > 0) & cam.in_image(np.round(px), margin=0.5), axis=1)
        ij = np.nan_to_num(np.round(px), nan=0.0).astype(np.int64)
        u, v = np.clip(ij[..., 0], 0, cam.width - 1), np.clip(ij[..., 1], 0, cam.height - 1)
        own_fg.append((m[v, u] > 0) & seen[:, None])
        boxes.append(body_box(cam, xy, radius))
    # explained[k] (D, h): column points inside the box of a kept person, per camera
    explained = [np.zeros((D, len(hz)), bool) for _ in cameras]
    for d in (int(i) for i in order):
        views = sum(int(np.sum(fg[d] & ~ex[d]) >= need) for fg, ex in zip(own_fg, explained))
        if views < views_needed[d]:
            continue
        keep[d] = True
        for k, p in enumerate(pts):
            if p is None or not np.all(np.isfinite(boxes[k][d])):
                continue
            x0, y0, x1, y1 = boxes[k][d]
            explained[k] |= (p[..., 0] >= x0) & (p[..., 0] <= x1) & (p[..., 1] >= y0) & (p[..., 1] <= y1)
    return keep
