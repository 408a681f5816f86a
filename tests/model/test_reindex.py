"""Re-indexing: slides of observed points along their outline, undone against a reconstruction
(silpose.model.robust.reindex), and its place in robust inference."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.model.robust.reindex import (ReindexSettings, fit_slide, index_offsets, reindex_contours,
                                   resample_by_index)
from silpose.model.robust import RobustSettings
from silpose.shared.contours import extract_contour

N = 200


def _figure(bite: tuple[int, int] | None = None, arm: int = 50) -> np.ndarray:
    """(240, 320) uint8 mask: a head, a torso, two legs and a raised arm; ``bite`` (x, y): a disc of radius 6 px
    removed there (a hole biting into the outline)."""
    m = np.zeros((240, 320), np.uint8)
    cv2.ellipse(m, (160, 58), (11, 13), 0, 0, 360, 1, -1)
    cv2.rectangle(m, (141, 72), (179, 138), 1, -1)
    cv2.rectangle(m, (144, 138), (157, 196), 1, -1)
    cv2.rectangle(m, (163, 138), (176, 196), 1, -1)
    cv2.line(m, (141, 80), (141 - arm // 2, 80 + arm), 1, 10)
    cv2.line(m, (179, 80), (190, 128), 1, 10)
    if bite is not None:
        cv2.circle(m, bite, 6, 0, -1)
    return m


def _outline(mask: np.ndarray) -> np.ndarray:
    return extract_contour(mask, N).points.astype(np.float64)


def test_index_offsets_against_brute_force():
    rng = np.random.default_rng(0)
    obs, rec = rng.normal(0, 20, (3, 40, 2)), rng.normal(0, 20, (3, 40, 2))
    offsets, dist = index_offsets(obs, rec, 5)
    for v in range(3):
        for i in range(40):
            cands = [(np.linalg.norm(obs[v, i] - rec[v, (i + s) % 40]), s) for s in range(-5, 6)]
            best = min(cands)
            assert offsets[v, i] == best[1] and dist[v, i] == pytest.approx(best[0])


def test_a_cyclic_shift_is_undone_exactly():
    clean = _outline(_figure())
    for shift in (3, -5):
        observed = np.roll(clean, -shift, axis=0)  # observed point i is reconstructed point i + shift
        out, changed = reindex_contours(observed[None, None], clean[None, None], np.ones((1, 1), bool))
        assert changed[0, 0]
        np.testing.assert_allclose(out[0, 0], clean, atol=1e-9)


def test_batches_larger_than_a_block_match_view_by_view():
    clean = _outline(_figure())
    shifts = np.arange(300) % 7 - 3  # 300 views: more than one block of views; shift 0 is left alone
    observed = np.stack([np.roll(clean, -s, axis=0) for s in shifts]).reshape(100, 3, N, 2)
    recon = np.broadcast_to(clean, observed.shape)
    out, changed = reindex_contours(observed, recon, np.ones((100, 3), bool))
    np.testing.assert_array_equal(changed.ravel(), shifts != 0)
    np.testing.assert_allclose(out, recon, atol=1e-9)


def test_a_smooth_slide_is_undone():
    clean = _outline(_figure())
    t = 2 * np.pi * np.arange(N) / N
    slide = 2.0 + 2.5 * np.sin(t) - 1.5 * np.cos(2 * t)  # points, a smooth periodic slide
    observed = resample_by_index(clean, np.arange(N) + slide)
    out, changed = reindex_contours(observed[None, None], clean[None, None], np.ones((1, 1), bool))
    assert changed[0, 0]
    before = np.linalg.norm(observed - clean, axis=-1).mean()
    after = np.linalg.norm(out[0, 0] - clean, axis=-1).mean()
    assert before > 3.0 and after < 0.25 * before, (before, after)
    offsets, dist = index_offsets(observed[None], clean[None], 8)
    fitted, chi2 = fit_slide(offsets[0], dist[0], 3.0, 3, 0.2236)
    assert np.abs(fitted - slide).max() < 0.6 and chi2 > 0.6 * N


def test_a_bitten_outline_ends_closer_to_the_clean_one_index_by_index():
    clean = _outline(_figure())
    bitten = _outline(_figure(bite=(141, 100)))  # the torso's left edge, below the arm
    out, changed = reindex_contours(bitten[None, None], clean[None, None], np.ones((1, 1), bool))
    assert changed[0, 0]
    before = np.linalg.norm(bitten - clean, axis=-1)
    after = np.linalg.norm(out[0, 0] - clean, axis=-1)
    assert np.median(after) < 0.6 * np.median(before), (np.median(before), np.median(after))


def test_jitter_and_displaced_stretches_are_left_alone(moved_in_place):
    clean = _outline(_figure())
    jittered, patched = moved_in_place(clean)
    batch = np.stack([clean, jittered, patched])[:, None]
    out, changed = reindex_contours(batch, np.repeat(clean[None, None], 3, axis=0), np.ones((3, 1), bool))
    assert not changed.any()
    np.testing.assert_array_equal(out, batch)
    out, changed = reindex_contours(batch, np.full_like(batch, np.nan), np.ones((3, 1), bool))  # no reconstruction
    assert not changed.any()
    out, changed = reindex_contours(np.roll(batch, 4, axis=2), batch, np.zeros((3, 1), bool))  # absent views
    assert not changed.any()
    with pytest.raises(ValueError, match="harmonics"):
        ReindexSettings(harmonics=-1)
    with pytest.raises(ValueError, match="reindex_passes"):
        RobustSettings(reindex_passes=-1)


@pytest.fixture(scope="module")
def arm_model():
    """A one-view model of the figure with its arm at several lengths (the joint height follows the arm), and
    inputs: held-out clean figures plus two with a bitten outline."""
    from silpose.model.shape_model import ShapeStructureModel

    arms = np.linspace(30, 70, 48).round().astype(int)
    contours = np.stack([_outline(_figure(arm=int(a))) for a in arms])[:, None]
    joints = np.zeros((len(arms), 19, 3))
    joints[:, :, 2] = np.linspace(0, 1, 19)[None] * arms[:, None] / 50.0
    held = np.arange(len(arms)) % 6 == 0
    model = ShapeStructureModel(n_components=2, n_latent=3, structure_weight=1.0, n_init=1, random_state=0,
                                joint_frame="metres").fit(contours[~held], joints[~held])
    bitten = np.stack([_outline(_figure(bite=(141, 100), arm=a)) for a in (40, 60)])[:, None]
    return model, np.concatenate([contours[held], bitten])


def test_infer_reindexes_only_what_slid_and_keeps_the_observed_log_marginal(arm_model):
    model, inputs = arm_model
    plain = model.infer(inputs, robust=RobustSettings(reindex_passes=0))
    res = model.infer(inputs, robust=True)
    assert plain.reindexed is not None and not plain.reindexed.any()
    assert res.reindexed[-2:].all()  # the bitten outlines
    untouched = ~res.reindexed.any(axis=1)
    assert untouched.any()
    np.testing.assert_array_equal(res.joints[untouched], plain.joints[untouched])
    np.testing.assert_array_equal(res.log_marginal, plain.log_marginal)  # of the input as observed
    # the final pass started from the re-indexed input
    changed = ~untouched
    assert not np.allclose(res.robust_input_px[changed], plain.robust_input_px[changed])
