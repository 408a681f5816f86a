"""Which blob is whose: per person and camera, the silhouette that is theirs alone, or why there is none.

A person at floor position (x, y) projects their torso column (the heights of :mod:`.floor`) into each
camera; the usable blob (:mod:`.blobs`) most of those points fall on is the person's candidate. It is
the person's silhouette only when (status :data:`VIEW_OK`):

- no other person's column falls on it (else :data:`VIEW_MERGED`: it holds someone else too, so its
  outline is not this person's);
- it does not touch the image border (:data:`VIEW_BORDER`: cut outline);
- it fits in the image box of a cylinder of radius :data:`BODY_RADIUS_M` and height
  :data:`BODY_HEIGHT_M` standing at the person's position (else :data:`VIEW_MERGED` too: the blob
  also holds something the floor grid did not find, e.g. a person outside the workspace).

Otherwise the view is missing for that person (the model marginalises it). Statuses for the camera as
a whole: :data:`VIEW_NO_VIDEO`, :data:`VIEW_ENDED` (the video stopped), :data:`VIEW_EMPTY` (no
foreground at all, e.g. an all-black mask), :data:`VIEW_NOT_SEEN` (the column falls on no usable blob),
:data:`VIEW_NOT_MODELLED` (a camera the model was not trained on).
"""

from __future__ import annotations

import numpy as np

from .blobs import Blobs
from .floor import COLUMN_HEIGHTS

VIEW_OK = "ok"
VIEW_MERGED = "merged"
VIEW_BORDER = "border"
VIEW_NOT_SEEN = "not seen"
VIEW_EMPTY = "empty mask"
VIEW_NO_VIDEO = "no video"
VIEW_ENDED = "video ended"
VIEW_NOT_MODELLED = "not modelled"
#: every per-view status, in report order
VIEW_STATUSES = (VIEW_OK, VIEW_MERGED, VIEW_BORDER, VIEW_NOT_SEEN, VIEW_EMPTY, VIEW_NO_VIDEO, VIEW_ENDED,
                 VIEW_NOT_MODELLED)
#: metres: radius of the cylinder a person's blob must fit in (arms and stride included)
BODY_RADIUS_M = 0.6
#: metres: its height
BODY_HEIGHT_M = 2.2
#: pixels of slack around the cylinder's box
BOX_SLACK_PX = 4.0

_RING = np.stack([np.cos(np.linspace(0, 2 * np.pi, 12, endpoint=False)),
                  np.sin(np.linspace(0, 2 * np.pi, 12, endpoint=False))], axis=1)


def body_box(cam, xy: np.ndarray) -> np.ndarray:
    """(P, 4) x0, y0, x1, y1 px: image box of the cylinder standing at floor points ``xy`` (P, 2)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    ring = xy[:, None, :] + BODY_RADIUS_M * _RING[None]  # (P, 12, 2)
    pts = np.concatenate([np.concatenate([ring, np.zeros(ring.shape[:2] + (1,))], -1),
                          np.concatenate([ring, np.full(ring.shape[:2] + (1,), BODY_HEIGHT_M)], -1)], axis=1)
    px = cam.project(pts)
    return np.concatenate([px.min(axis=1) - BOX_SLACK_PX, px.max(axis=1) + BOX_SLACK_PX], axis=1)


def assign_views(cam, blobs: Blobs, xy: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The blob of each of P people at floor points ``xy`` (P, 2) in one camera.

    Returns (labels (P,) int, the person's blob label or 0, statuses (P,) of :data:`VIEW_STATUSES`).
    """
    xy = np.asarray(xy, float).reshape(-1, 2)
    P = len(xy)
    if blobs.empty:
        return np.zeros(P, int), [VIEW_EMPTY] * P
    hz = np.asarray(COLUMN_HEIGHTS)
    pts = np.concatenate([np.repeat(xy[:, None], len(hz), 1), np.broadcast_to(hz[None, :, None], (P, len(hz), 1))], -1)
    px = np.round(cam.project(pts)).astype(int)  # (P, h, 2)
    lab = blobs.label_at(px)
    lab = np.where(blobs.usable[lab], lab, 0)
    mine = np.zeros(P, int)
    for p in range(P):
        hits = lab[p][lab[p] > 0]
        if hits.size:
            values, counts = np.unique(hits, return_counts=True)
            mine[p] = values[np.argmax(counts)]
    # every blob any person's column touches is claimed by that person
    claims: dict[int, set] = {}
    for p in range(P):
        for b in np.unique(lab[p][lab[p] > 0]):
            claims.setdefault(int(b), set()).add(p)
    boxes = body_box(cam, xy) if P else np.zeros((0, 4))
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
            x, y, w, h = blobs.bbox[b]
            x0, y0, x1, y1 = boxes[p]
            fits = x >= x0 and y >= y0 and x + w - 1 <= x1 and y + h - 1 <= y1
            status.append(VIEW_OK if fits else VIEW_MERGED)
    return mine, status
