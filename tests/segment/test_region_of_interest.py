"""BackgroundModel's fast path (per-frame region of interest, NCC and colour test at the candidates only,
cheaper clean-up) against the whole-frame pipeline composed from the dense building blocks: the same masks."""

import cv2
import numpy as np
import pytest

from silpose.segment import STAGES, BackgroundModel, cleanup
from silpose.segment.chroma import grow_shadows
from silpose.segment.ncc import background_window_stats, shadow_mask
from silpose.segment.synthetic import render_scene
from silpose.segment.validate import to_gray


@pytest.fixture(scope="module")
def scene():
    return render_scene(n_background=12, n_frames=3, size=(160, 120), seed=3)


def _whole_frame_reference(model: BackgroundModel, frame: np.ndarray, cand: np.ndarray) -> dict:
    """Steps 3-5 on the whole frame, from the dense public building blocks (the former pipeline)."""
    gray = to_gray(frame[None])[0]
    if model.colour_mean_ is None:
        frame = gray
    out = {"candidates": cand}
    kept = cand
    if model.ncc_threshold is not None:
        support = cand if model.ncc_support == "candidates" else None
        shadow = shadow_mask(gray, model._bg, support, model.min_support, model.ncc_threshold, model.shadow_ratio)
        if frame.ndim == 3 and model.chroma_max is not None:
            shadow = grow_shadows(frame, model.colour_mean_, cand, shadow & cand, model.shadow_ratio, model.chroma_max)
        kept = cand & ~shadow
    out["shadow_rejected"] = kept
    if model.edge_coverage is not None:
        kept = model._trim_edges(frame, kept)
    out["edges"] = kept
    m = cleanup.median(kept.view(np.uint8) * np.uint8(255), model.median_size)
    out["median"] = m > 0
    m = cleanup.open_close(m, model.open_size, model.close_size)
    if model.cleanup_guard is not None:
        strong, weak = _guard_reference(model, frame)
        near = cv2.dilate(m, np.ones((3, 3), np.uint8)) > 0
        m = np.where(((kept & strong & near) | (m > 0)) & ~(weak & ~kept), np.uint8(255), np.uint8(0))
    out["morphology"] = m > 0
    out["final"] = (cleanup.largest_blob(m) if model.largest_blob else m) > 0
    return out


def _guard_reference(model: BackgroundModel, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The clean-up guard's (strong, weak) (H, W) bool from its float64 definition: the normalised difference
    (RMS over the channels of colour frames) above / below cleanup_guard times k_sigma."""
    if frame.ndim == 3:
        z2 = (((frame - model.colour_mean_) / np.maximum(model.colour_std_, model.min_std)) ** 2).mean(axis=-1)
    else:
        z2 = ((frame - model.mean_) / np.maximum(model.std_, model.min_std)) ** 2
    s, w = model.cleanup_guard
    return z2 > (s * model.k_sigma) ** 2, z2 < (w * model.k_sigma) ** 2


@pytest.mark.parametrize(
    "params",
    [
        {},
        {"ncc_support": "window", "largest_blob": False},
        {"chroma_max": None, "noise_correction": False, "median_size": 5, "open_size": 1, "close_size": 7},
        {"edge_coverage": None, "colour": False},
        {"cleanup_guard": None},
        {"cleanup_guard": (1.2, 0.9), "colour": False, "close_size": 7},
    ],
)
def test_region_of_interest_gives_the_whole_frame_masks(scene, params):
    """The person in the middle and pushed against each border (the region then reaches the frame's edge), and
    a frame with a second, separate blob (the largest blob with several ones): every stage equal to the
    whole-frame pipeline's."""
    model = BackgroundModel(**params).fit(scene.background)
    f = scene.frames[1]
    frames = [f, np.roll(f, (-45, -60), axis=(0, 1)), np.roll(f, (40, 70), axis=(0, 1))]
    two = f.copy()
    two[5:25, 8:20] = 255 - two[5:25, 8:20]  # a separate blob far from the person
    frames.append(two)
    for frame in frames:
        got = model.segment(frame, return_stages=True)
        assert got["final"].sum() > 300
        want = _whole_frame_reference(model, frame, got["candidates"])
        for k in STAGES:
            np.testing.assert_array_equal(got[k], want[k], err_msg=k)


def test_shadow_mask_at_pixels_equals_the_dense_answer_there():
    rng = np.random.default_rng(4)
    h, w = 40, 50
    background = cv2.GaussianBlur(rng.uniform(20, 230, (h, w)), (0, 0), 1.0)
    frame = np.clip(np.rint(0.6 * background + rng.normal(0, 3, (h, w))), 0, 255).astype(np.uint8)
    bg = background_window_stats(background, 7, 1.0, np.full((h, w), 4.0))
    support = np.zeros((h, w), bool)
    support[5:30, 10:45] = rng.random((25, 35)) < 0.8
    at = support & (rng.random((h, w)) < 0.5)
    for sup in (support, None):
        dense = shadow_mask(frame, bg, sup, 0.25, 0.9, (0.25, 1.0))
        assert (dense & at).sum() > 50
        np.testing.assert_array_equal(shadow_mask(frame, bg, sup, 0.25, 0.9, (0.25, 1.0), at=at), dense & at)


def test_largest_blob_keeps_the_largest_and_the_first_of_equal_ones():
    mask = np.zeros((30, 40), np.uint8)
    mask[2:6, 2:6] = 255  # 16 px, first in raster order
    mask[20:24, 30:34] = 255  # 16 px
    np.testing.assert_array_equal(cleanup.largest_blob(mask) > 0, np.pad(np.ones((4, 4), bool), ((2, 24), (2, 34))))
    mask[10:15, 10:15] = 255  # 25 px: the largest
    want = np.zeros((30, 40), bool)
    want[10:15, 10:15] = True
    np.testing.assert_array_equal(cleanup.largest_blob(mask) > 0, want)
    one = np.zeros((30, 40), np.uint8)
    one[3:9, 4:7] = 255
    assert cleanup.largest_blob(one) is one  # a single blob: returned as it is


def test_colour_prefilter_bounds_never_exclude_a_shadow_like_pixel():
    """The uint8 per-channel bounds tried before the colour test hold every shadow-like pixel (and rule out most
    of the others), for pixels near the rule's limits."""
    from silpose.segment.chroma import shadow_like

    rng = np.random.default_rng(8)
    background = rng.integers(0, 256, (5, 60, 80, 3), dtype=np.uint8)
    model = BackgroundModel().fit(background)
    mean = model.colour_mean_
    alpha = rng.uniform(0.0, 1.3, (60, 80, 1))
    for spread in (2.0, 5.0, 12.0):  # chromaticity distortions around chroma_max = 6
        frame = np.clip(np.rint(alpha * mean + rng.normal(0, spread, mean.shape)), 0, 255).astype(np.uint8)
        like = shadow_like(frame, mean, model.shadow_ratio, model.chroma_max)
        inside = cv2.inRange(frame, model._like_lo, model._like_hi) > 0
        assert like.sum() > 100
        assert not (like & ~inside).any()
        assert (~inside).sum() > 0.2 * inside.size


@pytest.mark.parametrize("colour", [True, False])
def test_gain_division_channel_by_channel_equals_dividing_the_frame(scene, colour):
    """_normalise_gain (colour: convertScaleAbs channel by channel) gives what cv2.transform by the diagonal matrix
    of the inverse gains gives on the whole frame, pixel for pixel."""
    background = scene.background if colour else scene.background[..., 1]
    model = BackgroundModel(gain=True).fit(background)
    rng = np.random.default_rng(2)
    frames = rng.integers(0, 256, (3, *background.shape[1:]), dtype=np.uint8)
    frames[0] = np.clip(background[0] * 1.37, 0, 255).astype(np.uint8)  # brighter: gains > 1, saturation at 0/255
    got = model._normalise_gain(frames)
    for f, g in zip(frames, got):
        gain = model.frame_gain(f)
        if colour:
            want = cv2.transform(f, np.diag(1.0 / np.maximum(gain, 1e-3)).astype(np.float32))
        else:
            want = cv2.convertScaleAbs(f, alpha=float(1.0 / max(float(gain), 1e-3)))
        np.testing.assert_array_equal(g, want)


@pytest.mark.parametrize("gain", [0.25, 0.252, 0.998, 1.0, 1.002])
def test_shadows_at_the_candidates_near_the_ratio_bounds_are_the_dense_answer(gain):
    """Frames darkened to near the ratio bounds: asked at the candidates only, the shadow test gives the dense
    maps' answer there, pixel for pixel (the window sums are exact, whatever the rectangle they run over)."""
    rng = np.random.default_rng(int(gain * 100))
    h, w = 40, 50
    background = cv2.GaussianBlur(rng.uniform(30, 220, (h, w)), (0, 0), 1.0)
    frame = np.clip(np.rint(gain * background + rng.normal(0, 1.5, (h, w))), 0, 255).astype(np.uint8)
    bg = background_window_stats(background, 7, 1.0, np.full((h, w), 2.0))
    support = rng.random((h, w)) < 0.8
    dense = shadow_mask(frame, bg, support, 0.25, 0.5, (0.25, 1.0))
    assert (dense & support).sum() > 20
    np.testing.assert_array_equal(shadow_mask(frame, bg, support, 0.25, 0.5, (0.25, 1.0), at=support), dense & support)
