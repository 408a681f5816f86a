"""Metrics against independent brute-force references (cKDTree / pairwise distances / optimiser)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist
from scipy.spatial.transform import Rotation

from silpose.shared import metrics
from silpose.shared.contours import draw_contour, normalise


def _blob_contour(rng, cx, cy, rx, ry, n=200):
    """A wobbly closed curve (n, 2) px."""
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + 0.15 * np.sin(3 * th + rng.uniform(0, 6)) + 0.05 * np.cos(7 * th)
    return np.stack([cx + rx * r * np.cos(th), cy + ry * r * np.sin(th)], axis=1)


def _pixels(points, h, w):
    m = metrics.CANVAS_MARGIN_PX
    return np.argwhere(draw_contour(points + m, h + 2 * m, w + 2 * m)).astype(float)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_chamfer_one_sided_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    h, w = 240, 320
    true = _blob_contour(rng, 160, 120, 40, 90)
    recon = _blob_contour(rng, 160 + rng.uniform(-8, 8), 120 + rng.uniform(-8, 8), 35, 95)
    got = metrics.chamfer_one_sided(true, recon, h, w)
    t_pix, r_pix = _pixels(true, h, w), _pixels(recon, h, w)
    ref_tree = cKDTree(r_pix).query(t_pix)[0].mean()
    ref_pairwise = cdist(t_pix, r_pix).min(axis=1).mean()
    assert got == pytest.approx(ref_tree, rel=1e-5, abs=1e-5)
    assert got == pytest.approx(ref_pairwise, rel=1e-5, abs=1e-5)
    assert got > 0.5  # the two curves really differ


def test_chamfer_direction_and_symmetric_mean():
    rng = np.random.default_rng(5)
    h, w = 240, 320
    big = _blob_contour(rng, 160, 120, 60, 100)
    small = _blob_contour(rng, 140, 100, 10, 12)  # a small curve inside the big one
    true = np.stack([big, small])[None]  # (1, 2, n, 2): view 0 big->?, view 1 small->?
    recon = np.stack([small, big])[None]
    one, sym = metrics.chamfer_errors(true, recon, (h, w))
    b_pix, s_pix = _pixels(big, h, w), _pixels(small, h, w)
    d_big_to_small = cdist(b_pix, s_pix).min(axis=1).mean()
    d_small_to_big = cdist(s_pix, b_pix).min(axis=1).mean()
    assert one[0, 0] == pytest.approx(d_big_to_small, rel=1e-5)
    assert one[0, 1] == pytest.approx(d_small_to_big, rel=1e-5)
    assert one[0, 0] != pytest.approx(one[0, 1], rel=0.1)  # direction matters here
    assert sym[0, 0] == pytest.approx(0.5 * (d_big_to_small + d_small_to_big), rel=1e-5)
    assert sym[0, 1] == pytest.approx(sym[0, 0], rel=1e-5)


def test_chamfer_cache_gives_same_answer_and_nan_for_missing():
    rng = np.random.default_rng(3)
    true = np.stack([_blob_contour(rng, 150, 120, 40, 80) for _ in range(2)])[None]
    recon = true + rng.normal(0, 2, true.shape)
    recon[0, 1] = np.nan
    cache: dict = {}
    a = metrics.chamfer_errors(true, recon, (240, 320), cache=cache, keys=np.array([11]))
    b = metrics.chamfer_errors(true, recon, (240, 320), cache=cache, keys=np.array([11]))
    c = metrics.chamfer_errors(true, recon, (240, 320))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], c[1])
    assert np.isnan(a[0][0, 1]) and np.isfinite(a[0][0, 0])
    assert metrics.chamfer_one_sided(true[0, 0], true[0, 0], 240, 320) == 0.0


def test_reconstruction_leaving_the_image_is_not_clipped_within_margin():
    rng = np.random.default_rng(4)
    true = _blob_contour(rng, 20, 120, 30, 60)  # partly left of the image
    recon = true + np.array([3.0, 0.0])
    got = metrics.chamfer_one_sided(true, recon, 240, 320)
    assert 0 < got <= 3.0 + 1e-6


def test_pose_error_matches_loop_reference_and_ignores_global_translation():
    rng = np.random.default_rng(0)
    true = rng.normal(0, 0.4, (6, 19, 3))
    pred = true + rng.normal(0, 0.05, true.shape)
    ref = []
    for p, t in zip(pred, true):
        pr, tr = p - p[0], t - t[0]
        ref.append(100 * np.mean([np.sqrt(np.sum((pr[j] - tr[j]) ** 2)) for j in range(19)]))
    got = metrics.pose_error_cm(pred, true)
    np.testing.assert_allclose(got, ref, rtol=1e-12)
    np.testing.assert_allclose(metrics.pose_error_cm(pred + np.array([1.0, -2.0, 0.5]), true), ref, rtol=1e-9)
    with pytest.raises(ValueError, match="19, 3"):
        metrics.pose_error_cm(pred[:, :18], true[:, :18])


def test_procrustes_matches_optimiser_and_removes_similarity():
    rng = np.random.default_rng(1)
    true = rng.normal(0, 0.4, (3, 19, 3))
    rot = Rotation.random(3, random_state=2).as_matrix()
    moved = 1.3 * np.einsum("nij,nkj->nki", rot, true) + np.array([0.2, -0.1, 0.3])
    np.testing.assert_allclose(metrics.pose_error_procrustes_cm(moved, true), 0.0, atol=1e-9)
    pred = moved + rng.normal(0, 0.03, moved.shape)
    got = metrics.pose_error_procrustes_cm(pred, true)
    for i in range(3):
        def sse(v, x=pred[i], y=true[i]):
            a = Rotation.from_rotvec(v[:3]).as_matrix()
            return np.sum((np.exp(v[3]) * x @ a.T + v[4:] - y) ** 2)
        best = min((minimize(sse, np.r_[Rotation.random(random_state=s).as_rotvec(), 0, 0, 0, 0],
                             method="BFGS", options={"gtol": 1e-10}) for s in range(6)), key=lambda r: r.fun)
        a = Rotation.from_rotvec(best.x[:3]).as_matrix()
        aligned = np.exp(best.x[3]) * pred[i] @ a.T + best.x[4:]
        ref = 100 * np.linalg.norm(aligned - true[i], axis=1).mean()
        assert got[i] == pytest.approx(ref, rel=1e-4)
    assert np.all(got <= metrics.pose_error_cm(pred, true) + 1e-9)


def test_place_contours_uses_given_factors():
    rng = np.random.default_rng(2)
    px = rng.uniform(0, 300, (2, 3, 50, 2))
    q, c, s = normalise(px)
    np.testing.assert_allclose(metrics.place_contours(q, c, s), px, atol=1e-9)


def test_window_rasterisation_equals_whole_canvas():
    rng = np.random.default_rng(6)
    h, w = 240, 320
    m = metrics.CANVAS_MARGIN_PX
    for cx in (10.0, 160.0, 330.0):  # crossing the left edge, inside, crossing the right edge of the canvas
        pts = _blob_contour(rng, cx, 120, 40, 110)
        lo, hi = metrics._window(pts, h, w)
        got = metrics._pixels_in(pts, lo, hi)
        ref = _pixels(pts, h, w)[:, ::-1] - m  # (row, col) on the canvas -> (x, y) image coordinates
        assert sorted(map(tuple, got)) == sorted(map(tuple, ref.astype(int)))


def test_mask_iou_against_set_counting():
    rng = np.random.default_rng(0)
    a, b = rng.random((3, 20, 30)) < 0.4, rng.random((3, 20, 30)) < 0.5
    ref = [len(set(zip(*np.nonzero(x & y)))) / len(set(zip(*np.nonzero(x | y)))) for x, y in zip(a, b)]
    np.testing.assert_allclose(metrics.mask_iou(a, b), ref)
    assert metrics.mask_iou(a[0], b[0]) == pytest.approx(ref[0])


def test_mask_iou_empty_cases():
    z = np.zeros((4, 5), bool)
    o = z.copy()
    o[1, 1] = True
    assert metrics.mask_iou(z, z) == 1.0
    assert metrics.mask_iou(z, o) == 0.0
    with pytest.raises(ValueError):
        metrics.mask_iou(z, np.zeros((5, 4), bool))
