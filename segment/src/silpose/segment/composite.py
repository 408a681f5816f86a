"""Camera frames composited from known silhouettes (numpy + OpenCV; a Blender-free stand-in).

Given true masks (N samples x K cameras), each camera gets its own static textured room (the wall,
floor and props of :mod:`.synthetic`), seen in ``n_background`` empty frames and in one frame per
sample where the person is a differently coloured, striped cloth region given by the mask, with a
floor shadow beside the feet (an ellipse a quarter of the person's height long, where the background
is darkened by ``shadow_factor``). Every frame gets independent Gaussian camera noise and a global
illumination flicker (:mod:`silpose.shared.camera_noise`, computed in float32). The truth is the
mask itself, so segmentation can be scored exactly.
Images are BGR uint8 (``cv2.imwrite`` writes them as RGB PNGs).

All draws come from ``numpy.random.default_rng(SeedSequence([seed, camera]))`` for the room and
``SeedSequence([seed, camera, 1 + frame])`` / ``SeedSequence([seed, camera, 0, b])`` for the noise,
so a frame does not depend on how many others are made or in which chunks.
"""

from __future__ import annotations

import cv2
import numpy as np

from silpose.shared.camera_noise import add_camera_noise
from silpose.shared.seeds import derive_rng

from .synthetic import room_background, texture

#: cloth colour (BGR): light orange, far from the room's greys and browns in graylevel too
CLOTH_BGR = (70.0, 190.0, 250.0)


def room(camera: int, size: tuple[int, int], seed: int = 0) -> np.ndarray:
    """Noise-free background of one camera: (H, W, 3) float32 BGR, ``size`` = (W, H)."""
    w, h = size
    return room_background(derive_rng(seed, camera), h, w)


def background_frames(camera: int, size: tuple[int, int], n: int, seed: int = 0, noise_std: float = 3.0,
                      flicker: float = 0.02) -> np.ndarray:
    """``n`` empty-room frames of one camera: (n, H, W, 3) uint8 BGR."""
    clean = room(camera, size, seed)
    return np.stack([
        add_camera_noise(clean, derive_rng(seed, camera, 0, b), noise_std, flicker,
                         np.float32)
        for b in range(n)
    ])


def composite_frame(mask: np.ndarray, camera: int, frame: int, seed: int = 0, noise_std: float = 3.0,
                    flicker: float = 0.02, shadow_factor: float = 0.6, clean: np.ndarray | None = None) -> np.ndarray:
    """One camera frame with the person given by ``mask``.

    Parameters
    ----------
    mask : (H, W) bool or 0/1 uint8, the true silhouette
    camera, frame : indices that seed the noise (and, with ``clean=None``, select the room)
    shadow_factor : brightness multiplier of the floor shadow (1 = no shadow)
    clean : (H, W, 3) float32 room from :func:`room` (recomputed when None)

    Returns
    -------
    (H, W, 3) uint8 BGR
    """
    fg = np.asarray(mask).astype(bool)
    h, w = fg.shape
    if clean is None:
        clean = room(camera, (w, h), seed)
    rng = derive_rng(seed, camera, 1 + int(frame))
    img = clean.copy()
    ys, xs = np.nonzero(fg)
    if len(ys):
        feet_y, cx = int(ys.max()), float(xs.mean())
        height = int(ys.max() - ys.min() + 1)
        sh = np.zeros((h, w), np.uint8)
        axes = (max(8, int(0.25 * height)), max(4, int(0.06 * height)))
        cv2.ellipse(sh, (int(cx + 0.8 * axes[0]), feet_y - axes[1] // 2), axes, -6, 0, 360, 1, -1)
        img[sh.astype(bool)] *= np.float32(shadow_factor)
        stripes = 25.0 * (np.sin(np.arange(h, dtype=np.float32) * 0.7)[:, None] > 0)
        cloth = np.empty((h, w, 3), np.float32)
        cloth[:] = CLOTH_BGR
        cloth -= (stripes + np.abs(texture(rng, (h, w), 1.0, 6.0)))[..., None]
        img[fg] = cloth[fg]
    return add_camera_noise(img, rng, noise_std, flicker, np.float32)


def composite_people(masks: np.ndarray, clothing_bgr: np.ndarray, order: np.ndarray, camera: int, frame: int,
                     seed: int = 0, noise_std: float = 3.0, flicker: float = 0.02, shadow_factor: float = 0.6,
                     clean: np.ndarray | None = None, hip_share: float = 0.47) -> np.ndarray:
    """One camera frame with several people, each in their own clothes (:func:`composite_frame` for one).

    Parameters
    ----------
    masks : (P, H, W) bool, each person's own silhouette (as if alone)
    clothing_bgr : (P, 2, 3) uint8 BGR shirt and trousers colours; a person's rows above the share
        ``hip_share`` of their silhouette's height (from its top) wear the shirt, the rows below the trousers
    order : (P,) int, the people from the farthest to the nearest (nearer people are painted over farther ones)
    camera, frame, seed, noise_std, flicker, shadow_factor, clean : as :func:`composite_frame`

    Returns
    -------
    (H, W, 3) uint8 BGR
    """
    masks = np.asarray(masks).astype(bool)
    P, h, w = masks.shape
    if clean is None:
        clean = room(camera, (w, h), seed)
    rng = derive_rng(seed, camera, 1 + int(frame))
    img = clean.copy()
    boxes = []
    for p in range(P):
        ys, xs = np.nonzero(masks[p])
        boxes.append(None if not len(ys) else (int(ys.min()), int(ys.max()), float(xs.mean())))
    for p in range(P):  # shadows first: a shadow never covers a person
        if boxes[p] is None:
            continue
        top, feet_y, cx = boxes[p]
        height = feet_y - top + 1
        sh = np.zeros((h, w), np.uint8)
        axes = (max(8, int(0.25 * height)), max(4, int(0.06 * height)))
        cv2.ellipse(sh, (int(cx + 0.8 * axes[0]), feet_y - axes[1] // 2), axes, -6, 0, 360, 1, -1)
        img[sh.astype(bool) & ~masks.any(axis=0)] *= np.float32(shadow_factor)
    shade = (25.0 * (np.sin(np.arange(h, dtype=np.float32) * 0.7)[:, None] > 0)
             + np.abs(texture(rng, (h, w), 1.0, 6.0)))  # stripes and cloth texture, (H, W)
    rows = np.arange(h)[:, None]
    for p in np.asarray(order, int):
        if boxes[p] is None:
            continue
        top, feet_y, _ = boxes[p]
        upper = rows < top + hip_share * (feet_y - top + 1)  # (H, 1)
        cloth = np.where(upper[..., None], np.asarray(clothing_bgr[p, 0], np.float32),
                         np.asarray(clothing_bgr[p, 1], np.float32)) - shade[..., None]
        img[masks[p]] = np.clip(cloth, 0, 255)[masks[p]]
    return add_camera_noise(img, rng, noise_std, flicker, np.float32)
