"""Camera noise and illumination flicker added to clean renders (pure numpy, seeded).

Model (per frame, per pixel, per channel; values in 8-bit display levels 0..255):

    frame = clip(round(g * clean + e), 0, 255),   g ~ Uniform(1 - flicker, 1 + flicker) per frame,
                                                  e ~ Normal(0, sigma^2) per pixel and channel,

where ``clean`` (H, W, 3) float is the noise-free render in display levels (sRGB, 0..255). Over
many frames of one clean image, away from the clipping limits, each pixel has

    mean = clean,   variance = sigma^2 + clean^2 * flicker^2 / 3 + 1/12 (rounding).

Every frame's draws come from ``np.random.SeedSequence([NOISE_STREAM, seed, kind, camera, index])``
(kind 0 = background frame, 1 = person frame), so a frame is a pure function of its name.
"""

from __future__ import annotations

import numpy as np

NOISE_STREAM = 0x0015_E0C4
KINDS = {"background": 0, "frames": 1}


def noise_rng(seed: int, kind: str, camera: int, index: int) -> np.random.Generator:
    """Generator of the noise of frame ``index`` of ``kind`` ("background" | "frames") in camera ``camera``."""
    return np.random.default_rng(np.random.SeedSequence([NOISE_STREAM, int(seed), KINDS[kind], int(camera), int(index)]))


def add_camera_noise(clean: np.ndarray, rng: np.random.Generator, sigma: float, flicker: float) -> np.ndarray:
    """One noisy frame of ``clean`` (H, W, 3) float display levels -> (H, W, 3) uint8 (module docstring)."""
    clean = np.asarray(clean, np.float64)
    gain = rng.uniform(1.0 - flicker, 1.0 + flicker)
    noisy = gain * clean + rng.normal(0.0, sigma, size=clean.shape)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)


def expected_stats(clean: np.ndarray, sigma: float, flicker: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel (mean, std) of many noisy frames of ``clean`` (valid away from 0 and 255)."""
    clean = np.asarray(clean, np.float64)
    var = sigma**2 + clean**2 * flicker**2 / 3.0 + 1.0 / 12.0
    return clean, np.sqrt(var)
