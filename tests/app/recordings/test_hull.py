"""The visual-hull carving of :mod:`silpose.app.recordings.hull` against a per-voxel reference and a known shape."""

from __future__ import annotations

import cv2
import numpy as np

from silpose.app.recordings.hull import PersonHulls
from silpose.shared.camera import default_rig


def _box_image(cam, xy, size, base: float = 0.0) -> np.ndarray:
    """(H, W) uint8 0/1: the image of an axis-aligned box (size (sx, sy, h) m) standing at floor point ``xy``."""
    (x, y), (sx, sy, h) = xy, size
    corners = np.array([[x + a * sx / 2, y + b * sy / 2, z] for a in (-1, 1) for b in (-1, 1) for z in (base, base + h)])
    out = np.zeros((cam.height, cam.width), np.uint8)
    cv2.fillConvexPoly(out, np.round(cv2.convexHull(cam.project(corners).astype(np.float32))).astype(np.int32), 1)
    return out


def _reference_keep(hulls: PersonHulls, cams, masks, xy) -> np.ndarray:
    """The kept voxels of the box around ``xy``, one voxel and camera at a time from the module's definition:
    a camera sees a voxel when its centre's rounded image lies in the image, in front; it finds it foreground
    when a foreground pixel lies within its footprint (square window); kept when every seeing camera (of those
    with foreground) finds it, at least 2 see it, and it lies within the radius."""
    centres = hulls.centres(xy)
    flat = centres.reshape(-1, 3)
    keep = np.zeros(len(flat), bool)
    live = [k for k, m in enumerate(masks) if m is not None and m.any()]
    px = {k: cams[k].project(flat) for k in live}
    depth = {k: cams[k].to_camera(flat)[:, 2] for k in live}
    for i, c in enumerate(flat):
        if np.hypot(c[0] - xy[0], c[1] - xy[1]) > hulls.radius:
            continue
        seen = fg = 0
        for k in live:
            m, r = masks[k], int(hulls.footprint[k])
            u, v = np.round(px[k][i]).astype(int)
            if not (depth[k][i] > 0 and 0 <= u < m.shape[1] and 0 <= v < m.shape[0]):
                continue
            seen += 1
            fg += bool(m[max(0, v - r) : v + r + 1, max(0, u - r) : u + r + 1].any())
        keep[i] = seen >= 2 and fg == seen
    return keep.reshape(centres.shape[:3])


def test_carving_matches_a_per_voxel_reference():
    rig = default_rig()
    cams = list(rig)
    xy = (0.3, -0.2)
    rng = np.random.default_rng(3)
    masks = []
    for k, cam in enumerate(cams):  # a person-sized box, random speckle, and clutter in camera 1
        m = _box_image(cam, xy, (0.4, 0.3, 1.7))
        m |= (rng.random(m.shape) < 0.001).astype(np.uint8)
        if k == 1:
            m |= _box_image(cam, (1.2, 0.9), (0.5, 0.5, 1.0))
        masks.append(m)
    masks[3] = None  # a camera without a mask says nothing
    hulls = PersonHulls(cams, rig.workspace.bounds, rig.workspace.center, voxel=0.1, radius=0.6, height=2.0)
    hulls.carve([np.ones_like(m) if m is not None else None for m in masks], [(0.8, 0.5)])  # an earlier step, elsewhere
    boxes = hulls.prepare([xy])
    kept = hulls.in_box(hulls.keep([hulls.evidence(k, m, boxes) for k, m in enumerate(masks)], boxes)[0], boxes[0])
    assert kept.shape == hulls.centres(xy).shape[:3]
    ref = _reference_keep(hulls, cams, masks, xy)
    assert ref.sum() > 20 and ref.sum() < 0.5 * ref.size  # carved, not empty
    np.testing.assert_array_equal(kept, ref)


def test_a_box_keeps_its_whole_image_and_loses_the_clutter_one_camera_adds():
    rig = default_rig()
    cams = list(rig)
    xy, size = (0.0, 0.0), (0.4, 0.3, 1.7)
    truth = [_box_image(cam, xy, size) for cam in cams]
    masks = [t.copy() for t in truth]
    # clutter in camera 0 only: a slab from the box's side to the image's right border (a shelf changed since
    # the plate), touching the box's image
    ys, xs = np.nonzero(truth[0])
    masks[0][ys.min() + 10 : ys.max() - 20, xs.mean().astype(int):] = 1
    hulls = PersonHulls(cams, rig.workspace.bounds, rig.workspace.center)
    support = hulls.carve(masks, [xy])
    cut = [m & s for m, s in zip(masks, support)]
    for k in range(len(cams)):
        assert not (truth[k] & ~cut[k].astype(bool)).any(), k  # every pixel of the box is kept (a conservative hull)
    for k in range(1, len(cams)):
        np.testing.assert_array_equal(cut[k], truth[k])
    # camera 0 keeps of the slab only what the other three cameras' hull of the box covers there (measured 13 %,
    # up to 21 px from the box), and no longer reaches the border
    slab = masks[0].astype(bool) & ~truth[0].astype(bool)
    assert (cut[0].astype(bool) & slab).sum() < 0.2 * slab.sum()
    assert masks[0][:, -1].any() and not cut[0][:, -1].any()


def test_fewer_than_two_cameras_with_foreground_carve_nothing():
    rig = default_rig()
    cams = list(rig)
    masks = [_box_image(cams[0], (0.0, 0.0), (0.4, 0.3, 1.7))] + [np.zeros((c.height, c.width), np.uint8) for c in cams[1:]]
    hulls = PersonHulls(cams, rig.workspace.bounds, rig.workspace.center)
    assert hulls.carve(masks, [(0.0, 0.0)]) == [None] * len(cams)
