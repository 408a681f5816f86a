"""Working resolution: each camera's frames are processed at the size where a person is about
:data:`WORK_PERSON_PX` pixels tall, and the contours are scaled back to the rig camera's pixels.

The model needs 200 (or ``n_points``) contour points per view: a person 1,900 px tall in a full-HD portrait
frame gives the same contour, to about a per cent of its height, at 160 px (a ~450 px outline, 2 px between
points) -- the size the training data's people have (the default rig's are 114 px tall at the workspace
centre, the lab rig's 144-156 px). Segmenting, labelling,
tracing contours and drawing overlays all scale with the pixel count, so a 1080p camera is read, resized
(``cv2.INTER_AREA``, which averages the pixels it merges) and processed at about a sixth of its side:
the paper's background subtraction then costs about what it costs at the paper's 320x240. Cameras whose
person is already at most that tall (the default rig's 320x240, the lab's 644x486) keep their size.
Measured (``benchmarks/recordings.py``, rows ``colour``: 4 colour videos of 1932x1458 whose people are ~450 px
tall, 60 steps, a 2-core machine shared with other jobs): 3.5 time steps/s and 160 CPU ms per step at 160 px
(692x522), 1.35 steps/s at 320 px, 0.37 steps/s and 3.6 GB peak when every frame was processed at full size.

The person's height in a camera is measured from the rig: a 1.75 m column at the workspace centre,
projected. :func:`work_camera` is the rig camera seen at the working size: pixel centres map as
``x' = (x + 0.5) s - 0.5`` (OpenCV's resize), so ``K' = S K`` with that offset; the distortion
coefficients (in normalised coordinates) are unchanged. :func:`to_rig_px` maps points back.

:func:`shrink` resizes a frame to the working size in two stages: OpenCV's ``INTER_AREA`` by the largest whole
factor that divides both sides (a block average, OpenCV's fast path), then bilinear for the rest of the factor
(less than 2, where bilinear skips no pixel). ``INTER_AREA`` at a fractional factor takes OpenCV's general
path: measured on a 1932x1458 BGR frame shrunk to 692x522 (one thread, loaded 2-core machine), 19 ms in one
stage, 3.3 ms in two (mean absolute difference between the two: 1.9 grey levels on a noisy textured room). Both
stages map pixel centres as ``x' = (x + 0.5) s - 0.5``, so the composition does too and :func:`work_camera`
holds unchanged.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

#: pixels: the height a standing person at the workspace centre is given at the working resolution (the default
#: rig's people are 114 px tall at 320x240, where the segmentation's filters were chosen; the lab rig's ~150 px)
WORK_PERSON_PX = 160
#: metres: the height of the column whose image measures a person
PERSON_HEIGHT_M = 1.75


def person_height_px(cam, centre_xy) -> float:
    """Pixels between the images of the floor point ``centre_xy`` (2,) and the point 1.75 m above it."""
    x, y = (float(v) for v in centre_xy)
    px = cam.project(np.array([[x, y, 0.0], [x, y, PERSON_HEIGHT_M]]))
    return float(np.linalg.norm(px[1] - px[0]))


def work_size(cam, centre_xy, person_px: float = WORK_PERSON_PX) -> tuple[int, int]:
    """(width, height) the camera's frames are processed at: scaled so a person at ``centre_xy`` is about
    ``person_px`` tall, never enlarged (``person_px`` <= 0: the camera's own size)."""
    h = person_height_px(cam, centre_xy)
    if person_px <= 0 or not np.isfinite(h) or h <= person_px:
        return cam.width, cam.height
    s = person_px / h
    return max(16, int(round(cam.width * s))), max(16, int(round(cam.height * s)))


def work_camera(cam, size: tuple[int, int]):
    """The camera ``cam`` with frames resized to ``size`` (width, height): same pose, scaled intrinsics."""
    w, h = size
    if (w, h) == (cam.width, cam.height):
        return cam
    sx, sy = w / cam.width, h / cam.height
    K = np.array(cam.K, float).copy()
    K[0, :] *= sx
    K[1, :] *= sy
    K[0, 2] += 0.5 * sx - 0.5
    K[1, 2] += 0.5 * sy - 0.5
    return dataclasses.replace(cam, K=K, width=int(w), height=int(h))


def to_rig_px(points: np.ndarray, cam, work) -> np.ndarray:
    """Points (..., 2) in ``work``'s pixels (:func:`work_camera` of ``cam``) -> ``cam``'s pixels."""
    if work is cam:
        return points
    sx, sy = work.width / cam.width, work.height / cam.height
    return (np.asarray(points, float) + 0.5) / (sx, sy) - 0.5


def to_work_px(points: np.ndarray, cam, work) -> np.ndarray:
    """The inverse of :func:`to_rig_px`."""
    if work is cam:
        return points
    sx, sy = work.width / cam.width, work.height / cam.height
    return (np.asarray(points, float) + 0.5) * (sx, sy) - 0.5


def shrink(img: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``img`` (H, W) or (H, W, C) uint8 resized to ``size`` (width, height) <= its own: a whole-factor
    ``INTER_AREA`` stage then bilinear (module docstring); the plain ``INTER_AREA`` resize when no factor
    >= 2 divides both sides within the shrink."""
    h, w = img.shape[:2]
    tw, th = int(size[0]), int(size[1])
    if (tw, th) == (w, h):
        return img
    limit = int(min(w / tw, h / th))
    k = next((f for f in range(limit, 1, -1) if w % f == 0 and h % f == 0), 1)
    if k > 1:
        img = cv2.resize(img, (w // k, h // k), interpolation=cv2.INTER_AREA)
        if (w // k, h // k) == (tw, th):
            return img
        if w // k < 2 * tw and h // k < 2 * th:
            return cv2.resize(img, (tw, th), interpolation=cv2.INTER_LINEAR)
    return cv2.resize(img, (tw, th), interpolation=cv2.INTER_AREA)


#: a standing person's silhouette area over their image height squared (measured: the median of area / h^2 is
#: 0.18-0.19 per camera over 300 test samples x 4 views of the default dataset, h the silhouette's height)
PERSON_AREA_SHARE = 0.19
#: the minimum blob area as a share of a person's expected silhouette area: smaller blobs are speckle (docs/
#: conventions.md, "Minimum blob area"). 3 % gives 73 px for the default rig's 114 px people, 128 px for the lab
#: rig's 150 px and 146 px at the working resolution's 160 px
MIN_BLOB_SHARE = 0.03


def min_blob_area(cam, work, centre_xy, area_px: int | None = None) -> int:
    """The smallest usable blob, pixels at ``work``'s resolution (:func:`work_camera` of ``cam``).

    ``area_px`` (pixels of ``cam``, e.g. ``--min-area``) scaled to ``work``; by default
    ``MIN_BLOB_SHARE * PERSON_AREA_SHARE * h**2``, h the height of a person at ``centre_xy`` at the working
    resolution (:func:`person_height_px`; the image's half height when the rig cannot say).
    """
    if area_px is not None:
        return max(1, int(round(area_px * work.width * work.height / (cam.width * cam.height))))
    h = person_height_px(work, centre_xy)
    if not np.isfinite(h) or h <= 0:
        h = work.height / 2
    return max(1, int(round(MIN_BLOB_SHARE * PERSON_AREA_SHARE * h * h)))
