"""Registering an empty-room plate to the recording it is the background of (an addition for real rooms).

A plate shot at another time is rarely where the recording's camera is to the pixel: a camera nudged
on its tripod, a phone re-mounted, a video rescaled by the recorder (1080 -> 1088 px). Background
subtraction compares pixel with pixel, so a shift of a few pixels makes every textured edge of the
room foreground. :func:`plate_alignment` finds the affine warp that maps the plate onto a view of the
empty room taken from the recording itself (the per-pixel median of frames spread over it: people
who move are not in it), by maximising their enhanced correlation coefficient (ECC; Evangelidis and
Psarakis, "Parametric image alignment using enhanced correlation coefficient maximization", IEEE
TPAMI 30(10), 2008; OpenCV's ``cv2.findTransformECC``), which ignores gain and offset, so a lighting
change between plate and recording does not bias it. The warp is kept only when it is small (a
nudge, not another viewpoint: :data:`MAX_SHIFT`, :data:`MAX_SCALE`) and raises the correlation; the
plate frames are then warped before the background is learnt (:func:`warp_plate`).

A plate shot at another time also differs from the recording where nothing moved: another exposure
curve, compression, a cushion put back. The per-pixel spread of the plate's own frames (what the
paper's model thresholds against) measures none of that -- a still plate's is zero. The robust spread
of the plate's differences from the recording's view of the room, over the whole frame,
:func:`plate_mismatch_std`, does: it is the floor a pixel's standard deviation gets
(``BackgroundModel.min_std``), so a pixel is foreground only when it differs from the plate by more than
the room itself does. People cover a minority of the pixels and the median ignores them.
"""

from __future__ import annotations

import cv2
import numpy as np

from .validate import to_gray

#: largest translation accepted, as a fraction of the image's larger side
MAX_SHIFT = 0.05
#: largest change of scale (and shear) accepted: the warp's 2x2 part within this of the identity
MAX_SCALE = 0.05
#: smallest gain in correlation for a warp to replace the identity
MIN_GAIN = 0.01
#: ECC is run on images of at most this many pixels on their larger side (the warp is scaled back)
ALIGN_SIDE = 480
#: the plate's gain and mismatch are measured on every GRID_STEP-th row and column where it is brighter than DARK
GRID_STEP, DARK = 4, 16
#: standard deviation of a normal variable over its median absolute deviation
MAD_TO_STD = 1.4826


def _ecc(template: np.ndarray, image: np.ndarray, warp: np.ndarray) -> tuple[float, np.ndarray] | None:
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-5)
    try:
        return cv2.findTransformECC(template, image, warp.astype(np.float32), cv2.MOTION_AFFINE, criteria, None, 5)
    except cv2.error:  # no convergence (a flat image, or nothing in common)
        return None


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Zero-mean normalised correlation of two images of one size (graylevels, any dtype)."""
    x = a.astype(np.float64).ravel() - a.mean()
    y = b.astype(np.float64).ravel() - b.mean()
    d = float(np.sqrt((x @ x) * (y @ y)))
    return float(x @ y / d) if d > 0 else 0.0


def plate_alignment(plate: np.ndarray, room: np.ndarray) -> np.ndarray | None:
    """(2, 3) float64 affine warp ``W`` with ``room(x) ~ plate(W x)`` (pixels of the full size), or None when
    the identity is as good or the best warp is not a small one (module docstring).

    Args:
        plate: (H, W) or (H, W, 3) uint8 empty-room frame.
        room: the recording's view of the room, same size (e.g. the per-pixel median of its frames).
    """
    g_plate, g_room = to_gray(np.asarray(plate)[None])[0], to_gray(np.asarray(room)[None])[0]
    if g_plate.shape != g_room.shape:
        raise ValueError(f"plate {g_plate.shape} and room {g_room.shape} differ in size")
    h, w = g_plate.shape
    s = min(1.0, ALIGN_SIDE / max(h, w))
    size = (max(8, round(w * s)), max(8, round(h * s)))
    small = [cv2.resize(g, size, interpolation=cv2.INTER_AREA).astype(np.float32) for g in (g_room, g_plate)]
    found = _ecc(small[0], small[1], np.eye(2, 3))
    if found is None:
        return None
    warp = found[1].astype(np.float64)
    sx, sy = size[0] / w, size[1] / h
    warp[0, 2] /= sx  # translation back to full-size pixels (the 2x2 part is scale-free for equal sx, sy)
    warp[1, 2] /= sy
    warp[0, 1] *= sy / sx
    warp[1, 0] *= sx / sy
    if (np.abs(warp[:, :2] - np.eye(2)).max() > MAX_SCALE
            or np.abs(warp[:, 2]).max() > MAX_SHIFT * max(h, w)):
        return None
    before = correlation(g_room, g_plate)
    after = correlation(g_room, warp_plate(g_plate, warp))
    return warp if after >= before + MIN_GAIN else None


def warp_plate(frame: np.ndarray, warp: np.ndarray) -> np.ndarray:
    """``frame`` (H, W[, 3]) resampled through ``warp`` (:func:`plate_alignment`): pixel x of the result is the
    frame's pixel ``warp @ (x, 1)``, bilinear, the border replicated."""
    h, w = frame.shape[:2]
    return cv2.warpAffine(frame, np.asarray(warp, np.float64), (w, h),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)


def plate_mismatch_std(plate: np.ndarray, room: np.ndarray) -> float:
    """Robust standard deviation (graylevels) of ``room / gain - plate`` over a grid of pixels: ``1.4826 x`` the
    median absolute difference, after dividing ``room`` by its per-channel gain over the plate (the median ratio,
    as :class:`~silpose.segment.BackgroundModel` does with ``gain=True``), on pixels where the plate is brighter
    than :data:`DARK` (module docstring). ``plate`` and ``room``: (H, W[, 3]) uint8 of one size."""
    b = np.asarray(plate, np.float32)[::GRID_STEP, ::GRID_STEP]
    r = np.asarray(room, np.float32)[::GRID_STEP, ::GRID_STEP]
    if b.shape != r.shape:
        raise ValueError(f"plate {np.shape(plate)} and room {np.shape(room)} differ in size")
    b, r = b.reshape(-1, b.shape[-1] if b.ndim == 3 else 1), r.reshape(-1, r.shape[-1] if r.ndim == 3 else 1)
    lit = np.all(b > DARK, axis=1)
    if lit.sum() < 16:
        return 0.0
    gain = np.median(r[lit] / b[lit], axis=0)
    return float(MAD_TO_STD * np.median(np.abs(r[lit] / np.maximum(gain, 1e-6) - b[lit])))
