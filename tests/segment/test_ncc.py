"""The box-filter local NCC (silpose.segment.ncc) against a brute-force per-pixel loop."""

import numpy as np
import pytest

from silpose.segment.ncc import background_window_stats, local_ncc


def _bruteforce(frame, background, window, support, min_support, min_texture, noise_var=None):
    """Per-pixel NCC and brightness ratio in float64 with reflect-101 borders, by explicit loops.

    Returns ncc (H, W) with 0 where undefined (noise-corrected when noise_var is given), and
    ratio (H, W) (nan where the support is too small).
    """
    r = window // 2
    pad = lambda a: np.pad(np.asarray(a, np.float64), r, mode="reflect")  # numpy reflect == REFLECT_101
    fp, bp = pad(frame), pad(background)
    np_ = pad(np.zeros(frame.shape) if noise_var is None else noise_var)
    cp = pad(np.ones(frame.shape) if support is None else support).astype(bool)
    h, w = frame.shape
    ncc = np.zeros((h, w))
    ratio = np.full((h, w), np.nan)
    for y in range(h):
        for x in range(w):
            sel = cp[y : y + window, x : x + window]
            if sel.mean() < min_support or not sel.any():
                continue
            a = fp[y : y + window, x : x + window][sel]
            b = bp[y : y + window, x : x + window][sel]
            ratio[y, x] = a.mean() / b.mean()
            if b.std() < min_texture or a.var() <= 1e-4:
                continue
            ncc[y, x] = ((a - a.mean()) * (b - b.mean())).mean() / (a.std() * b.std())
            if noise_var is not None:
                reliability = max(1 - np_[y : y + window, x : x + window][sel].mean() / a.var(), 0.5)
                ncc[y, x] = min(ncc[y, x] / np.sqrt(reliability), 1.0)
    return ncc, ratio


@pytest.mark.parametrize("window", [3, 5, 7])
@pytest.mark.parametrize("use_support", [False, True])
@pytest.mark.parametrize("noise", [False, True])
def test_box_filter_ncc_equals_bruteforce(window, use_support, noise):
    rng = np.random.default_rng(window + 10 * use_support)
    h, w = 19, 23
    background = rng.uniform(20, 230, (h, w))
    # A shadowed patch (a*b + c, NCC -> 1), an unrelated patch (NCC ~ 0), a flat patch (no texture).
    frame = background + rng.normal(0, 3, (h, w))
    frame[2:10, 3:12] = 0.5 * background[2:10, 3:12] + 4 + rng.normal(0, 1, (8, 9))
    frame[10:17, 12:20] = rng.uniform(0, 255, (7, 8))
    background[14:19, 0:8] = 77.0
    frame = np.clip(np.rint(frame), 0, 255).astype(np.uint8)
    support = rng.random((h, w)) < 0.6 if use_support else None
    min_support, min_texture = 0.25, 1.5

    noise_var = rng.uniform(4, 40, (h, w)) if noise else None
    bg = background_window_stats(background, window, min_texture, noise_var)
    ncc, ratio = local_ncc(frame, bg, support, min_support)
    ref_ncc, ref_ratio = _bruteforce(
        frame, background, window, support, min_support if use_support else 0, min_texture, noise_var
    )

    assert ncc.shape == (h, w) and ncc.dtype == np.float32
    np.testing.assert_allclose(ncc, ref_ncc, atol=2e-4)
    defined = np.isfinite(ref_ratio)
    np.testing.assert_array_equal(np.isnan(ratio), np.isnan(ref_ratio))
    np.testing.assert_allclose(ratio[defined], ref_ratio[defined], rtol=1e-4)
    # The test is not vacuous: both high correlations (shadow) and zeros (flat/undefined) occur.
    assert (ref_ncc > 0.9).sum() > 10 and (ref_ncc == 0).sum() > 5


def test_shadow_like_change_correlates_and_unrelated_change_does_not():
    rng = np.random.default_rng(3)
    background = rng.uniform(40, 220, (40, 40))
    bg = background_window_stats(background, 7, 2.0)
    shadow = np.clip(0.5 * background + rng.normal(0, 2, background.shape), 0, 255).astype(np.uint8)
    other = rng.integers(0, 256, background.shape).astype(np.uint8)
    ncc_shadow, ratio_shadow = local_ncc(shadow, bg)
    ncc_other, _ = local_ncc(other, bg)
    assert np.median(ncc_shadow) > 0.95 and abs(np.median(ncc_other)) < 0.3
    assert abs(np.median(ratio_shadow) - 0.5) < 0.05


def test_candidate_support_far_from_the_image_border_and_at_it():
    """The cropped computation (bounding box of qualifying windows) equals the brute force wherever
    the support sits: in the interior, touching each border, or absent."""
    rng = np.random.default_rng(11)
    h, w, window = 30, 34, 5
    background = rng.uniform(20, 230, (h, w))
    frame = np.clip(np.rint(0.6 * background + rng.normal(0, 4, (h, w))), 0, 255).astype(np.uint8)
    bg = background_window_stats(background, window, 1.0, np.full((h, w), 9.0))
    for region in [(slice(10, 18), slice(12, 20)), (slice(0, 6), slice(0, 9)), (slice(24, 30), slice(27, 34)), None]:
        support = rng.random((h, w)) < 0.02  # sparse specks: (almost surely) never enough support
        if region is not None:
            support[region] = rng.random(support[region].shape) < 0.9
        ncc, ratio = local_ncc(frame, bg, support, 0.3)
        ref_ncc, ref_ratio = _bruteforce(frame, background, window, support, 0.3, 1.0, np.full((h, w), 9.0))
        np.testing.assert_allclose(ncc, ref_ncc, atol=2e-4)
        np.testing.assert_array_equal(np.isnan(ratio), np.isnan(ref_ratio))
        ok = np.isfinite(ref_ratio)
        np.testing.assert_allclose(ratio[ok], ref_ratio[ok], rtol=1e-4)
        assert (region is None) == (not ok.any())


def test_noise_correction_lifts_a_noisy_shadow_to_high_correlation_but_not_noise():
    """Deep shadow (x0.3) on a noisy camera: raw NCC falls below 0.9, the corrected one does not;
    an unrelated textured patch stays uncorrelated."""
    rng = np.random.default_rng(4)
    h, w, s = 60, 60, 5.0
    background = rng.uniform(60, 200, (h, w))  # texture std ~40
    shadow = np.clip(np.rint(0.2 * background + rng.normal(0, s, (h, w))), 0, 255).astype(np.uint8)
    other = np.clip(np.rint(rng.uniform(30, 90, (h, w)) + rng.normal(0, s, (h, w))), 0, 255).astype(np.uint8)
    plain = background_window_stats(background, 7, 2.0)
    corrected = background_window_stats(background, 7, 2.0, np.full((h, w), s * s))
    assert np.median(local_ncc(shadow, plain)[0]) < 0.9 < np.median(local_ncc(shadow, corrected)[0])
    assert np.percentile(np.abs(local_ncc(other, corrected)[0]), 99) < 0.7


def test_the_largest_window_on_extreme_graylevels_equals_bruteforce():
    """Window 63 (the largest allowed) over black and white backgrounds and frames: the exact integer sums do not
    overflow (their largest products approach 2^62) and give the brute force's NCC and ratio."""
    rng = np.random.default_rng(63)
    h, w = 70, 66
    background = np.where(rng.random((h, w)) < 0.5, 0.0, 255.0)
    frame = np.where(rng.random((h, w)) < 0.5, 0, 255).astype(np.uint8)
    frame[:, :30] = (0.5 * background[:, :30] + 3).astype(np.uint8)  # a shadow: NCC 1 over its windows
    support = rng.random((h, w)) < 0.9
    noise_var = rng.uniform(0, 255.0**2, (h, w))
    bg = background_window_stats(background, 63, 1.5, noise_var)
    ncc, ratio = local_ncc(frame, bg, support, 0.25)
    ref_ncc, ref_ratio = _bruteforce(frame, background, 63, support, 0.25, 1.5, noise_var)
    np.testing.assert_allclose(ncc, ref_ncc, atol=2e-4)
    np.testing.assert_allclose(ratio, ref_ratio, rtol=1e-4)
    assert np.ptp(ref_ncc) > 0.1 and np.isfinite(ref_ratio).all()


@pytest.mark.parametrize("shape", [(3, 4), (2, 9), (1, 6), (5, 1)])
def test_a_window_larger_than_the_frame_reflects_again_as_bruteforce(shape):
    """Frames smaller than the window (7 here): the window's reach is reflected as often as it takes (reflect-101,
    as OpenCV's box filters and numpy's padding), never read outside the frame."""
    rng = np.random.default_rng(sum(shape))
    background = rng.uniform(20, 230, shape)
    frame = np.clip(np.rint(0.5 * background + rng.normal(0, 2, shape) + 3), 0, 255).astype(np.uint8)
    support = rng.random(shape) < 0.8
    bg = background_window_stats(background, 7, 0.5, None)
    ncc, ratio = local_ncc(frame, bg, support, 0.25)
    ref_ncc, ref_ratio = _bruteforce(frame, background, 7, support, 0.25, 0.5)
    np.testing.assert_allclose(ncc, ref_ncc, atol=2e-4)
    np.testing.assert_array_equal(np.isnan(ratio), np.isnan(ref_ratio))
    defined = np.isfinite(ref_ratio)
    assert defined.any()
    np.testing.assert_allclose(ratio[defined], ref_ratio[defined], rtol=1e-4)


def test_statistics_of_another_size_are_refused_before_the_compiled_loop():
    from silpose.segment.ncc import shadow_mask

    bg = background_window_stats(np.full((10, 12), 100.0), 5, 1.0, None)
    support = np.ones((10, 13), bool)
    with pytest.raises(ValueError, match="one shape"):
        shadow_mask(np.zeros((10, 13), np.uint8), bg, support, 0.25, 0.9, (0.25, 1.0), at=support)
