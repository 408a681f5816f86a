"""Camera sensor noise and illumination flicker added to clean images (pure numpy, seeded).

The one noise model of silpose's rendered and composited camera frames (datagen's textured
frames, segment's composited test scenes). Per frame, per pixel, per channel, in 8-bit display
levels 0..255:

    frame = clip(round(g * clean + e), 0, 255),   g ~ Uniform(1 - flicker, 1 + flicker) per frame,
                                                  e ~ Normal(0, sigma^2) per pixel and channel,

where ``clean`` (H, W, C) is the noise-free image. The gain is drawn first, then the per-pixel
noise, from the caller's generator. Over many frames of one clean image, away from the clipping
limits, each pixel has

    mean = clean,   variance = sigma^2 + clean^2 * flicker^2 / 3 + 1/12 (rounding).

Rendered frames draw from :func:`noise_rng`, ``derive_rng(CAMERA_NOISE_STREAM, seed,
NOISE_KIND[kind], camera, index)`` (docs/conventions.md, "Seeds"), so a frame is a pure function
of its name.
"""

from __future__ import annotations

import numpy as np

from .seeds import CAMERA_NOISE_STREAM, NOISE_KIND, derive_rng

__all__ = ["noise_rng", "add_camera_noise", "expected_stats"]


def noise_rng(seed: int, kind: str, camera: int, index: int) -> np.random.Generator:
    """Generator of the noise of frame ``index`` of ``kind`` ("background" | "frames") in camera ``camera``."""
    if kind not in NOISE_KIND:
        raise ValueError(f"camera noise kind must be one of {tuple(NOISE_KIND)}, got {kind!r}")
    return derive_rng(CAMERA_NOISE_STREAM, seed, NOISE_KIND[kind], camera, index)


def add_camera_noise(
    clean: np.ndarray, rng: np.random.Generator, sigma: float, flicker: float, dtype: type = np.float64
) -> np.ndarray:
    """One noisy frame of ``clean`` (module docstring).

    Args:
        clean: (H, W, C) float display levels 0..255 (any array shape works).
        rng: the frame's generator (one gain draw, then one normal draw per value).
        sigma: standard deviation of the additive noise, display levels.
        flicker: half-width of the gain's uniform distribution.
        dtype: arithmetic precision of ``g * clean + e`` (``np.float32`` or ``np.float64``); the
            noise is drawn in float64 either way.
    Returns:
        an array of ``clean``'s shape, uint8.
    """
    x = np.asarray(clean, dtype)
    gain = dtype(rng.uniform(1.0 - flicker, 1.0 + flicker))
    noisy = x * gain + rng.normal(0.0, sigma, size=x.shape).astype(dtype, copy=False)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)


def expected_stats(clean: np.ndarray, sigma: float, flicker: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel (mean, std) of many noisy frames of ``clean`` (valid away from 0 and 255)."""
    clean = np.asarray(clean, np.float64)
    var = sigma**2 + clean**2 * flicker**2 / 3.0 + 1.0 / 12.0
    return clean, np.sqrt(var)
