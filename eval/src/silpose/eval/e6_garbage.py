"""Inputs that are not a person, for the plausibility check of E6 (``silpose.eval.e6_inference``).

Every kind is a set of per-view binary masks of the rig's image size, turned into contours like
real input (``silpose.shared.contours.extract_contour``: the outer boundary of the largest blob):

- ``all-white``: every pixel foreground (the contour is the image border);
- ``all-black``: no foreground at all (no view can be used: ``silpose infer`` reports the frame as
  ``no silhouette``; there is nothing to infer from);
- ``noise``: RGB noise (uniform 8-bit per channel) converted to grey and thresholded at 127, as
  ``silpose infer`` reads a PNG;
- ``rectangle``: a filled person-sized rectangle (80-130 px tall, 25-60 px wide) at a random place,
  drawn independently in each view;
- ``box``: a 3D box (0.3-0.7 m wide and deep, 1.4-1.9 m tall) standing at a random point of the
  workspace, projected through the rig (so the views agree like a real object's would);
- ``two people merged``: the masks of two test walkers, the second moved beside the first (feet
  level) in every view just far enough that the two form one blob (:func:`merge_side_by_side`: what
  background subtraction gives for two people walking side by side, touching).

Draws come from ``derive_rng(seed, stream_code("garbage"), kind index)`` (``silpose.shared.seeds``).
"""

from __future__ import annotations

import cv2
import numpy as np

from silpose.shared.contours import EmptyMaskError, extract_contour
from silpose.shared.seeds import derive_rng, stream_code

__all__ = ["GARBAGE_KINDS", "garbage_masks", "merge_side_by_side", "masks_to_contours"]

GARBAGE_KINDS = ("all-white", "all-black", "noise", "rectangle", "box", "two people merged")


def _project(cam, points: np.ndarray) -> np.ndarray:
    """(m, 2) px of world points (m, 3) through an OpenCV pinhole camera (no distortion)."""
    x = (cam.K @ (cam.R @ points.T + np.asarray(cam.t, dtype=np.float64).reshape(3, 1))).T
    return x[:, :2] / x[:, 2:3]


def garbage_masks(kind: str, n: int, rig, seed: int = 0, person_masks: np.ndarray | None = None) -> np.ndarray:
    """(n, K, H, W) uint8 0/1 masks of one garbage ``kind`` (module doc) for the K cameras of ``rig``.

    ``person_masks`` (N, K, H, W): test masks for "two people merged" (needs N >= 2).
    """
    if kind not in GARBAGE_KINDS:
        raise ValueError(f"unknown garbage kind {kind!r}; choose from {GARBAGE_KINDS}")
    cams = list(rig.cameras)
    h, w = int(cams[0].height), int(cams[0].width)
    k = len(cams)
    rng = derive_rng(seed, stream_code("garbage"), GARBAGE_KINDS.index(kind))
    out = np.zeros((n, k, h, w), dtype=np.uint8)
    for i in range(n):
        for v in range(k):
            if kind == "all-white":
                out[i, v] = 1
            elif kind == "noise":
                rgb = rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8)
                out[i, v] = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY) > 127
            elif kind == "rectangle":
                rh, rw = int(rng.integers(80, 131)), int(rng.integers(25, 61))
                y, x = int(rng.integers(5, h - rh - 5)), int(rng.integers(5, w - rw - 5))
                out[i, v, y : y + rh, x : x + rw] = 1
        if kind == "box":
            cx, cy = rng.uniform(-1.0, 1.0, size=2)
            bw, bd, bh = rng.uniform(0.3, 0.7), rng.uniform(0.3, 0.7), rng.uniform(1.4, 1.9)
            corners = np.array([[cx + sx * bw / 2, cy + sy * bd / 2, z] for sx in (-1, 1) for sy in (-1, 1)
                                for z in (0.0, bh)])
            for v, cam in enumerate(cams):
                hull = cv2.convexHull(_project(cam, corners).astype(np.float32))
                cv2.fillConvexPoly(out[i, v], np.round(hull).astype(np.int32), 1)
        elif kind == "two people merged":
            if person_masks is None or len(person_masks) < 2:
                raise ValueError("garbage kind 'two people merged' needs person_masks with at least 2 walkers")
            a_idx, b_idx = rng.choice(len(person_masks), size=2, replace=False)
            for v in range(k):
                out[i, v] = merge_side_by_side(np.asarray(person_masks[a_idx, v]) > 0,
                                               np.asarray(person_masks[b_idx, v]) > 0)
    return out


def _shifted(mask: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """``mask`` moved by (dx, dy) px, pixels moved off the image dropped."""
    h, w = mask.shape
    out = np.zeros_like(mask)
    src = mask[max(0, -dy) : h - max(0, dy), max(0, -dx) : w - max(0, dx)]
    out[max(0, dy) : max(0, dy) + src.shape[0], max(0, dx) : max(0, dx) + src.shape[1]] = src
    return out


def merge_side_by_side(a: np.ndarray, b: np.ndarray, min_share: float = 0.95) -> np.ndarray:
    """(H, W) bool union of two person masks, ``b`` moved beside ``a`` (feet level) just far enough
    into it that the union is one blob: its largest 8-connected blob holds >= ``min_share`` of the pixels."""
    xa, xb = np.flatnonzero(a.any(axis=0)), np.flatnonzero(b.any(axis=0))
    ya, yb = np.flatnonzero(a.any(axis=1)), np.flatnonzero(b.any(axis=1))
    dy = int(ya.max() - yb.max())
    start = int(xa.max() - xb.min())  # b's left edge on a's right edge
    union = a | _shifted(b, start, dy)
    for dx in range(start, start - len(xb) - 1, -1):
        union = a | _shifted(b, dx, dy)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(union.astype(np.uint8), connectivity=8)
        if n > 1 and stats[1:, cv2.CC_STAT_AREA].max() >= min_share * union.sum():
            break
    return union


def masks_to_contours(masks: np.ndarray, n_points: int) -> tuple[np.ndarray, np.ndarray]:
    """(contours (N, K, n, 2) px, NaN where empty; present (N, K) bool) of masks (N, K, H, W)."""
    n, k = masks.shape[:2]
    contours = np.full((n, k, n_points, 2), np.nan)
    present = np.zeros((n, k), dtype=bool)
    for i in range(n):
        for v in range(k):
            try:
                contours[i, v] = extract_contour(masks[i, v], n_points).points
                present[i, v] = True
            except EmptyMaskError:
                pass
    return contours, present
