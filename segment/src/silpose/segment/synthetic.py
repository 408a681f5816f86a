"""Synthetic camera scenes with known masks, for tests and the benchmark (numpy + OpenCV only).

A scene is a static textured background (a floor and a wall with blurred-noise texture, a few
coloured boxes as props), seen in ``n_background`` empty frames and ``n_frames`` frames with a
walking figure. Every frame gets independent Gaussian camera noise and a global illumination
flicker (a gain close to 1). The figure (torso, head, limbs: a bright, striped cloth texture of
its own) casts a shadow on the floor: an ellipse beside its feet where the background is
multiplied by ``shadow_factor``; the shadow is hidden where the figure covers it.

All random draws come from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class SyntheticScene:
    """Frames and truth of one synthetic scene (images are BGR uint8).

    background : (n_background, H, W, 3) empty-scene frames
    frames : (n_frames, H, W, 3) frames with the figure and its shadow
    masks : (n_frames, H, W) bool, true figure masks
    shadows : (n_frames, H, W) bool, visible shadow pixels (shadow and not figure)
    clean_background : (H, W, 3) float32, the noise-free background
    """

    background: np.ndarray
    frames: np.ndarray
    masks: np.ndarray
    shadows: np.ndarray
    clean_background: np.ndarray


def texture(rng: np.random.Generator, shape: tuple[int, int], sigma: float, amplitude: float) -> np.ndarray:
    """Blurred Gaussian noise (H, W) float32 with standard deviation ``amplitude``."""
    t = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), sigma)
    return t * np.float32(amplitude / max(float(t.std()), 1e-6))


def room_background(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """Noise-free textured room (H, W, 3) float32 BGR: a wall, a floor and three boxes as props."""
    horizon = int(0.45 * h)
    img = np.empty((h, w, 3), np.float32)
    img[:horizon] = (150.0, 140.0, 120.0)  # wall (BGR)
    img[horizon:] = (90.0, 110.0, 120.0)  # floor
    tex = texture(rng, (h, w), 1.2, 22.0) + texture(rng, (h, w), 4.0, 10.0)
    img += tex[..., None]
    for _ in range(3):  # props
        x0, y0 = int(rng.integers(0, w - 40)), int(rng.integers(0, h - 40))
        colour = rng.uniform(40, 200, 3)
        cv2.rectangle(img, (x0, y0), (x0 + int(rng.integers(15, 40)), y0 + int(rng.integers(15, 40))), colour.tolist(), -1)
        img[y0 : y0 + 40, x0 : x0 + 40] += texture(rng, (min(40, h - y0), min(40, w - x0)), 1.0, 12.0)[..., None]
    return np.clip(img, 0, 255)


def _figure_mask(h: int, w: int, cx: float, phase: float) -> tuple[np.ndarray, tuple[int, int]]:
    """(H, W) uint8 figure mask at horizontal position cx, walking phase in radians; and its feet point."""
    m = np.zeros((h, w), np.uint8)
    s = h / 240.0
    top, hip, feet = int(0.15 * h), int(0.55 * h), int(0.92 * h)
    cxi = int(round(cx))
    cv2.circle(m, (cxi, top + int(12 * s)), int(11 * s), 1, -1)  # head
    cv2.ellipse(m, (cxi, (top + hip) // 2 + int(8 * s)), (int(17 * s), (hip - top) // 2 - int(4 * s)), 0, 0, 360, 1, -1)
    swing = np.sin(phase)
    for sign in (-1, 1):
        foot = (cxi + int(sign * swing * 22 * s), feet)
        cv2.line(m, (cxi + sign * int(7 * s), hip), foot, 1, int(12 * s))  # legs
        hand = (cxi - int(sign * swing * 18 * s) + sign * int(20 * s), hip + int(5 * s))
        cv2.line(m, (cxi + sign * int(16 * s), top + int(32 * s)), hand, 1, int(8 * s))  # arms
    return m, (cxi, feet)


def render_scene(
    n_background: int = 20,
    n_frames: int = 8,
    size: tuple[int, int] = (320, 240),
    seed: int = 0,
    noise_std: float = 3.0,
    flicker: float = 0.02,
    shadow_factor: float = 0.55,
) -> SyntheticScene:
    """Render a synthetic scene.

    Parameters
    ----------
    n_background, n_frames : numbers of empty and figure frames
    size : (W, H) in pixels
    seed : seed of the scene's random generator
    noise_std : per-pixel, per-channel Gaussian noise standard deviation, graylevels
    flicker : global gain of each frame drawn uniformly in [1 - flicker, 1 + flicker]
    shadow_factor : background brightness multiplier inside the shadow (0 < factor < 1)
    """
    w, h = size
    rng = np.random.default_rng(seed)
    clean = room_background(rng, h, w)
    cloth = np.empty((h, w, 3), np.float32)
    stripes = 30.0 * (np.sin(np.arange(h, dtype=np.float32) * 0.6)[:, None] > 0)
    cloth[:] = (60.0, 170.0, 230.0)  # orange-ish cloth (BGR), brighter than the floor
    cloth += (stripes + texture(rng, (h, w), 1.0, 10.0))[..., None]

    def noisy(img: np.ndarray) -> np.ndarray:
        gain = rng.uniform(1.0 - flicker, 1.0 + flicker)
        out = img * np.float32(gain) + rng.normal(0.0, noise_std, img.shape).astype(np.float32)
        return np.clip(np.rint(out), 0, 255).astype(np.uint8)

    background = np.stack([noisy(clean) for _ in range(n_background)]) if n_background else np.zeros((0, h, w, 3), np.uint8)
    frames = np.empty((n_frames, h, w, 3), np.uint8)
    masks = np.empty((n_frames, h, w), bool)
    shadows = np.empty((n_frames, h, w), bool)
    for i in range(n_frames):
        cx = (0.25 + 0.5 * i / max(n_frames - 1, 1)) * w
        fig, (fx, fy) = _figure_mask(h, w, cx, phase=0.9 * i)
        sh = np.zeros((h, w), np.uint8)
        cv2.ellipse(sh, (fx + int(0.16 * w), fy - int(0.02 * h)), (int(0.15 * w), int(0.05 * h)), -8, 0, 360, 1, -1)
        fg = fig.astype(bool)
        shadow = sh.astype(bool) & ~fg
        img = clean.copy()
        img[shadow] *= np.float32(shadow_factor)
        img[fg] = cloth[fg]
        frames[i] = noisy(img)
        masks[i] = fg
        shadows[i] = shadow
    return SyntheticScene(background, frames, masks, shadows, clean)
