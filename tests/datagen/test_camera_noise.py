"""The one camera-noise model (``silpose.shared.camera_noise``) used by datagen's textured frames
and segment's composited scenes: moments, seed recipe and the exact draws of both former copies."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.shared.camera_noise import add_camera_noise, expected_stats, noise_rng

SIGMA, FLICKER = 2.0, 0.02


def _ramp() -> np.ndarray:
    return np.tile(np.linspace(20, 230, 64), (8, 1))[..., None].repeat(3, -1)


def test_noise_model_moments():
    """add_camera_noise against expected_stats on many frames of a ramp (pure numpy)."""
    clean = _ramp()
    frames = np.stack([add_camera_noise(clean, noise_rng(1, "background", 0, j), SIGMA, FLICKER) for j in range(3000)])
    mean, std = expected_stats(clean, SIGMA, FLICKER)
    np.testing.assert_allclose(frames.mean(0), mean, atol=0.25)
    np.testing.assert_allclose(frames.std(0), std, rtol=0.08)


def test_noise_rng_keeps_the_frames_datasets_seed_recipe():
    """The stream keys are part of the data format: SeedSequence([0x0015E0C4, seed, kind, camera, index])
    with kind background = 0, frames = 1 (written out here, independently of silpose.shared.seeds)."""
    for (seed, kind, code, cam, idx) in [(3, "background", 0, 1, 7), (0, "frames", 1, 0, 0), (11, "frames", 1, 3, 5)]:
        ref = np.random.default_rng(np.random.SeedSequence([0x0015E0C4, seed, code, cam, idx])).uniform(size=5)
        np.testing.assert_array_equal(noise_rng(seed, kind, cam, idx).uniform(size=5), ref)
    with pytest.raises(ValueError, match="kind"):
        noise_rng(0, "foreground", 0, 0)


def test_float64_draws_equal_the_former_datagen_formula():
    clean = _ramp().astype(np.float32) + 0.3
    rng = np.random.default_rng(5)
    gain = rng.uniform(1.0 - FLICKER, 1.0 + FLICKER)
    ref = np.clip(np.rint(gain * clean.astype(np.float64) + rng.normal(0.0, SIGMA, size=clean.shape)), 0, 255)
    out = add_camera_noise(clean, np.random.default_rng(5), SIGMA, FLICKER)
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out, ref.astype(np.uint8))


def test_float32_draws_equal_the_former_segment_formula():
    img = (_ramp() * 1.01).astype(np.float32)
    rng = np.random.default_rng(9)
    gain = rng.uniform(1.0 - FLICKER, 1.0 + FLICKER)
    ref = img * np.float32(gain) + rng.normal(0.0, 3.0, img.shape).astype(np.float32)
    ref = np.clip(np.rint(ref), 0, 255).astype(np.uint8)
    np.testing.assert_array_equal(add_camera_noise(img, np.random.default_rng(9), 3.0, FLICKER, np.float32), ref)


def test_clipping_and_zero_noise():
    clean = np.array([[[-5.0, 0.4, 254.6], [300.0, 127.5, 10.0]]])
    np.testing.assert_array_equal(add_camera_noise(clean, np.random.default_rng(0), 0.0, 0.0),
                                  [[[0, 0, 255], [255, 128, 10]]])
