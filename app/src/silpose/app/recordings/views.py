"""Which blob is whose: per person and camera, the silhouette that is theirs alone, or why there is none.

A person at floor position (x, y) projects their torso column (the heights of :mod:`.floor`) into each
camera; the usable blob (:mod:`.blobs`) most of those points fall on is the person's candidate. It is
the person's silhouette only when (status :data:`VIEW_OK`):

- no other person's column falls on it (else :data:`VIEW_MERGED`: it holds someone else too, so its
  outline is not this person's);
- it does not touch the image border (:data:`VIEW_BORDER`: cut outline);
- it fits in the image box of a cylinder of radius :data:`BODY_RADIUS_M` and height
  :data:`BODY_HEIGHT_M` standing at the person's position (else :data:`VIEW_CLUTTER`: the blob also
  holds something no tracked person explains -- a prop, a shadow, someone outside the workspace; "merged"
  is kept for blobs two tracked people share; the pipeline makes clutter that stays background, so such a
  view comes back);
- it spans the person from the feet to above the torso: its box reaches the image of the floor point
  (within :data:`FOOT_TOLERANCE_M`) and of the point :data:`MIN_TOP_M` above it (within
  :data:`TOP_TOLERANCE_M`) -- else :data:`VIEW_PARTIAL`. Real background subtraction breaks a person
  into pieces where their clothes match the background (a torso blob and a legs blob), and furniture
  or a nearer person hides part of them; such a piece is not the person's silhouette.

Otherwise the view is missing for that person (the model marginalises it).

:func:`grounded` tells real people from the floor grid's ghosts (with cameras on one wall, the rays
through two people also cross behind and between them): a person's blob ends, below their torso, at
their own feet -- within :data:`FOOT_TOLERANCE_M` of where the floor point projects -- in every camera
where nobody nearer hides their feet; a ghost's torso column lies on someone else's blob, which ends at
that someone's feet, nearer or farther. Measured on the lab recording with four walkers (one frame in
three): 85 % of the real detections were grounded in at least one camera, 29 % of the ghosts; with two
walkers, 99 % of the real ones. The pipeline lets only grounded detections start a track, and explains the grid's
ghosts away with the detections grounded in more cameras first (:mod:`.ghosts`). Statuses for the camera as
a whole: :data:`VIEW_NO_VIDEO`, :data:`VIEW_ENDED` (the video stopped), :data:`VIEW_EMPTY` (no
foreground at all, e.g. an all-black mask), :data:`VIEW_NOT_SEEN` (the column falls on no usable blob),
:data:`VIEW_NOT_MODELLED` (a camera the model was not trained on).
"""

from __future__ import annotations

import numpy as np

from ..view_status import (VIEW_BORDER, VIEW_CLUTTER, VIEW_EMPTY, VIEW_ENDED, VIEW_MERGED, VIEW_NO_VIDEO,  # noqa: F401
                           VIEW_NOT_MODELLED, VIEW_NOT_SEEN, VIEW_OK, VIEW_PARTIAL, VIEW_STATUSES)
from .blobs import Blobs
from .floor import COLUMN_HEIGHTS

#: metres: radius of the cylinder a person's blob must fit in: arms, stride, and someone seated with their
#: legs forward and the chair under them (0.6 m marked every view of a seated person in a public 4-camera
#: recording "merged": the feet and chair legs reach 0.7 m from the head's vertical)
BODY_RADIUS_M = 0.9
#: metres: its height
BODY_HEIGHT_M = 2.2
#: pixels of slack around the cylinder's box
BOX_SLACK_PX = 4.0
#: metres: a blob ends at a person's feet within this distance of their floor point (:func:`grounded`)
FOOT_TOLERANCE_M = 0.2
#: metres: a person's blob reaches at least this far above the floor: above the hips of an adult (a legs-only
#: piece ends near 0.9-1.0 m), below the head of someone seated on a chair (about 1.3 m)
MIN_TOP_M = 1.1
#: metres: slack of the top test
TOP_TOLERANCE_M = 0.05
#: metres: half-width of the image band below the torso searched for the feet
FOOT_BAND_M = 0.15

_RING = np.stack([np.cos(np.linspace(0, 2 * np.pi, 12, endpoint=False)),
                  np.sin(np.linspace(0, 2 * np.pi, 12, endpoint=False))], axis=1)


def _ring_points(xy: np.ndarray, radius: float) -> np.ndarray:
    """(P, 24, 3) world points of the cylinders of ``radius`` metres at floor points ``xy`` (P, 2): 12 round the
    floor, 12 round the top (:data:`BODY_HEIGHT_M`)."""
    ring = xy[:, None, :] + radius * _RING[None]  # (P, 12, 2)
    return np.concatenate([np.concatenate([ring, np.zeros(ring.shape[:2] + (1,))], -1),
                           np.concatenate([ring, np.full(ring.shape[:2] + (1,), BODY_HEIGHT_M)], -1)], axis=1)


def _box_of(px: np.ndarray) -> np.ndarray:
    """(P, 4) x0, y0, x1, y1 px: the box of each person's projected cylinder points ``px`` (P, m, 2), with slack."""
    return np.concatenate([px.min(axis=1) - BOX_SLACK_PX, px.max(axis=1) + BOX_SLACK_PX], axis=1)


def body_box(cam, xy: np.ndarray, radius: float = BODY_RADIUS_M) -> np.ndarray:
    """(P, 4) x0, y0, x1, y1 px: image box of the cylinder of ``radius`` metres standing at floor points ``xy``
    (P, 2)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    return _box_of(cam.project(_ring_points(xy, radius)))


def _column_points(xy: np.ndarray) -> np.ndarray:
    """(P, h, 3) world points of the torso columns (:data:`~.floor.COLUMN_HEIGHTS`) above floor points ``xy``."""
    hz = np.asarray(COLUMN_HEIGHTS)
    P = len(xy)
    return np.concatenate([np.repeat(xy[:, None], len(hz), 1), np.broadcast_to(hz[None, :, None], (P, len(hz), 1))], -1)


def _labels_at(blobs: Blobs, px: np.ndarray) -> np.ndarray:
    """Usable blob labels (0: none) at projected points ``px`` (..., 2) (rounded; NaN: beyond the lens model)."""
    lab = blobs.label_at(np.nan_to_num(np.round(px), nan=-1.0).astype(int))
    return np.where(blobs.usable[lab], lab, 0)


def _column_labels(cam, blobs: Blobs, xy: np.ndarray) -> np.ndarray:
    """(P, h) usable blob labels (0: none) under the torso columns of people at floor points ``xy`` (P, 2)."""
    return _labels_at(blobs, cam.project(_column_points(xy)))


def _main_label(lab_row: np.ndarray) -> int:
    """The label most of a column's points fall on (ties: the smallest), 0 if none; a few points, so Python."""
    counts: dict[int, int] = {}
    for v in lab_row.tolist():
        if v > 0:
            counts[v] = counts.get(v, 0) + 1
    return min(counts, key=lambda v: (-counts[v], v)) if counts else 0


def person_labels(cam, blobs: Blobs, xy: np.ndarray) -> np.ndarray:
    """(P,) int: the usable blob most of each person's torso column falls on (0: none), people at floor points
    ``xy`` (P, 2) -- each person's candidate blob (module docstring)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    if blobs.empty or not len(xy):
        return np.zeros(len(xy), int)
    return np.array([_main_label(row) for row in _column_labels(cam, blobs, xy)], int)


def grounded(cam, blobs: Blobs, xy: np.ndarray) -> np.ndarray:
    """(P,) bool: the blob under each person's torso ends at their feet in this camera (module docstring)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    out = np.zeros(len(xy), bool)
    if blobs.empty or not len(xy):
        return out
    lab = _column_labels(cam, blobs, xy)
    feet = np.zeros((len(xy), 3))  # the floor points (z = 0)
    feet[:, :2] = xy
    foot_px = cam.project(feet)
    depth = cam.to_camera(feet)[:, 2]
    ox, oy = blobs.origin
    h, w = blobs.labels.shape
    for p in range(len(xy)):
        b = _main_label(lab[p])
        if b == 0 or depth[p] <= 0 or not np.all(np.isfinite(foot_px[p])):  # NaN: beyond the lens model
            continue
        f = cam.K[0, 0] / depth[p]
        u = int(round(foot_px[p, 0])) - ox
        half = max(2, int(round(FOOT_BAND_M * f)))
        band = blobs.labels[:, max(0, u - half) : max(0, min(w, u + half + 1))]
        rows = np.flatnonzero((band == b).any(axis=1))
        if rows.size:
            out[p] = abs(rows[-1] + oy - foot_px[p, 1]) <= FOOT_TOLERANCE_M * f
    return out


def assign_views(cam, blobs: Blobs, xy: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The blob of each of P people at floor points ``xy`` (P, 2) in one camera.

    Returns (labels (P,) int, the person's blob label or 0, statuses (P,) of :data:`VIEW_STATUSES`).
    Every person's points (torso column, body cylinder, floor point and the point :data:`MIN_TOP_M` above it) are
    projected in one call.
    """
    xy = np.asarray(xy, float).reshape(-1, 2)
    P = len(xy)
    if blobs.empty:
        return np.zeros(P, int), [VIEW_EMPTY] * P
    cols, ring = _column_points(xy), _ring_points(xy, BODY_RADIUS_M)
    span = np.zeros((P, 2, 3))  # (P, 2, 3): the floor point and the point MIN_TOP_M above it
    span[:, :, :2] = xy[:, None]
    span[:, 1, 2] = MIN_TOP_M
    pts = np.concatenate([cols, ring, span], axis=1)
    h, r = cols.shape[1], ring.shape[1]
    depth = cam.to_camera(pts[:, h + r:])[..., 2]  # (P, 2)
    px = cam.project(pts)
    lab = _labels_at(blobs, px[:, :h])
    mine = np.array([_main_label(row) for row in lab], int)
    # every blob any person's column touches is claimed by that person
    claims: dict[int, set] = {}
    for p, row in enumerate(lab.tolist()):
        for b in set(row) - {0}:
            claims.setdefault(int(b), set()).add(p)
    boxes = _box_of(px[:, h : h + r]) if P else np.zeros((0, 4))
    status = []
    for p in range(P):
        b = int(mine[p])
        if b == 0:
            status.append(VIEW_NOT_SEEN)
        elif len(claims[b]) > 1:
            status.append(VIEW_MERGED)
        elif blobs.touches_border[b]:
            status.append(VIEW_BORDER)
        else:
            x, y, w, bh = blobs.bbox[b]
            x0, y0, x1, y1 = boxes[p]
            fits = x >= x0 and y >= y0 and x + w - 1 <= x1 and y + bh - 1 <= y1
            if not fits:
                status.append(VIEW_CLUTTER)
            else:
                ok = _spans(blobs.bbox[b], px[p, h + r:], cam.K[0, 0], depth[p])
                status.append(VIEW_OK if ok else VIEW_PARTIAL)
    return mine, status


def spans_person(cam, bbox: np.ndarray, xy: np.ndarray) -> bool:
    """True if a blob's box ``bbox`` (x, y, width, height px) reaches the images of the floor point ``xy``
    (2,) and of the point :data:`MIN_TOP_M` above it, each within its tolerance (module docstring).

    Tolerances are metres at the person's distance (``f / depth`` px per metre); the boxes are compared in
    image coordinates, so a rolled camera is handled like an upright one."""
    pts = np.array([[xy[0], xy[1], 0.0], [xy[0], xy[1], MIN_TOP_M]])
    return _spans(bbox, cam.project(pts), cam.K[0, 0], cam.to_camera(pts)[:, 2])


def _spans(bbox: np.ndarray, px: np.ndarray, f: float, depth: np.ndarray) -> bool:
    """:func:`spans_person` from the projected floor and top points ``px`` (2, 2), the focal length ``f`` px and
    their depths (2,) metres."""
    x, y, w, h = (float(v) for v in bbox)
    if np.any(depth <= 0):
        return False
    per_m = f / depth
    for (u, v), tol in zip(px, (FOOT_TOLERANCE_M * per_m[0], TOP_TOLERANCE_M * per_m[1])):
        if not (x - tol <= u <= x + w - 1 + tol and y - tol <= v <= y + h - 1 + tol):
            return False
    return True
