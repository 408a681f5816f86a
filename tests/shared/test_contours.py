"""Tests of silpose.shared.contours against analytic shapes, brute force and OpenCV."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from silpose.shared.contours import (
    Contour,
    EmptyMaskError,
    denormalise,
    draw_contour,
    extract_contour,
    extract_contours,
    normalise,
    signed_area,
)

H, W = 240, 320


def ellipse_mask(cx, cy, a, b, h=H, w=W):
    """(h, w) bool: pixel centres inside the axis-aligned ellipse (semi-axes a along x, b along y)."""
    yy, xx = np.mgrid[:h, :w]
    return ((xx - cx) / a) ** 2 + ((yy - cy) / b) ** 2 <= 1.0


def figure_mask(arm_up: bool, h=H, w=W):
    """A stick-ish person: torso rectangle, head disc, one arm either hanging or raised beside the head."""
    m = np.zeros((h, w), bool)
    m[95:200, 140:180] = True  # torso, x 140..179, overlapping the head (y 62..98)
    m |= ellipse_mask(159.5, 80, 14, 18, h, w)  # head: top near y = 62
    if arm_up:
        m[30:110, 182:190] = True  # arm raised: top at y = 30, above the head
        m[100:110, 179:182] = True  # joined to the shoulder
    else:
        m[100:180, 182:190] = True
        m[100:110, 179:182] = True
    return m


def dist_to_polyline(points, poly):
    """(n,) distance of each point to the closed polyline poly (m, 2), by brute force over segments."""
    a = poly
    b = np.roll(poly, -1, axis=0)
    ab = b - a
    ap = points[:, None, :] - a[None]
    t = np.clip(np.sum(ap * ab, -1) / np.maximum(np.sum(ab * ab, -1), 1e-12), 0, 1)
    proj = a[None] + t[..., None] * ab[None]
    return np.min(np.linalg.norm(points[:, None, :] - proj, axis=-1), axis=1)


# ---------------------------------------------------------------- extraction on analytic shapes


def test_ellipse_points_on_boundary_equal_spacing_clockwise_start_at_top():
    cx, cy, a, b = 160.3, 120.6, 40.0, 60.0
    c = extract_contour(ellipse_mask(cx, cy, a, b), n_points=200)
    assert isinstance(c, Contour)
    assert c.points.shape == (200, 2) and c.points.dtype == np.float32
    p = c.points.astype(np.float64)
    # Within ~1 px of the analytic boundary (dense reference polygon of the true ellipse).
    th = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    truth = np.stack([cx + a * np.cos(th), cy + b * np.sin(th)], axis=1)
    assert dist_to_polyline(p, truth).max() < 1.0
    # Equal arc spacing: chords between consecutive points (closing one included) nearly equal,
    # and they add up to about the raw perimeter.
    chords = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    assert chords.std() / chords.mean() < 0.05
    # (the raw 8-connected staircase is a few per cent longer than the chords cutting across it)
    assert 0.94 * c.length < chords.sum() <= c.length
    # Orientation: clockwise on screen means positive shoelace area in (x, y-down) ...
    assert signed_area(p) > 0
    assert abs(signed_area(p) - cv2.contourArea(p.astype(np.float32))) < 1e-3 * abs(signed_area(p))
    # ... and, checked geometrically: moving right at the top and down at the rightmost point.
    assert p[1, 0] > p[0, 0]
    right = int(np.argmax(p[:, 0]))
    assert p[(right + 1) % 200, 1] > p[right - 1, 1]
    # Start point: top of the ellipse above the centroid (boundary pixel centres lie inside the edge).
    assert abs(p[0, 0] - cx) < 0.5
    assert 0 <= p[0, 1] - (cy - b) < 1.0
    # Raw area and perimeter against brute force / OpenCV.
    assert c.area == int(ellipse_mask(cx, cy, a, b).sum())
    assert c.n_blobs == 1 and not c.touches_border


def test_signed_area_sign_convention_on_a_hand_made_square():
    # (0,0) -> (1,0) -> (1,1) -> (0,1): right, then down on screen = clockwise on screen.
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    assert signed_area(sq) == pytest.approx(1.0)
    assert signed_area(sq[::-1]) == pytest.approx(-1.0)
    # A mask square is traced clockwise whatever findContours' own orientation is.
    m = np.zeros((20, 20), bool)
    m[5:15, 4:12] = True
    c = extract_contour(m, 40)
    assert signed_area(c.points) == pytest.approx(cv2.contourArea(c.points), rel=1e-5)
    assert signed_area(c.points) > 0


def test_start_stays_at_head_top_when_an_arm_rises():
    down, up = figure_mask(False), figure_mask(True)
    topmost = [np.flatnonzero(m.any(axis=1))[0] for m in (down, up)]
    assert topmost[0] - topmost[1] > 25  # the topmost pixel jumps from the head to the hand
    head_top = np.flatnonzero(ellipse_mask(159.5, 80, 14, 18).any(axis=1))[0]
    starts = []
    for m in (down, up):
        c = extract_contour(m, 200)
        ys, xs = np.nonzero(m)
        assert abs(c.points[0, 0] - xs.mean()) < 1e-3  # on the vertical through the centroid
        assert c.points[0, 1] == pytest.approx(head_top, abs=1.0)  # at the head top
        starts.append(c.points[0].astype(float))
    assert np.linalg.norm(starts[0] - starts[1]) < 3.0


def test_start_is_the_farthest_up_crossing_for_a_u_shape():
    # A U whose centroid lies in the gap: the vertical through it crosses the bottom bar only.
    m = np.zeros((60, 60), bool)
    m[10:50, 10:20] = True
    m[10:50, 40:50] = True
    m[40:50, 10:50] = True
    c = extract_contour(m, 100)
    ys, xs = np.nonzero(m)
    assert c.points[0, 0] == pytest.approx(xs.mean(), abs=1e-3)
    assert c.points[0, 1] == pytest.approx(40.0, abs=1e-4)  # top edge of the bottom bar


def test_largest_blob_is_chosen_and_blobs_counted_8_connected():
    m = ellipse_mask(200, 120, 30, 30)
    m |= ellipse_mask(60, 60, 10, 10)
    m[200:205, 30:35] = True
    big = ellipse_mask(200, 120, 30, 30)
    c = extract_contour(m, 100)
    assert c.n_blobs == 3
    assert c.area == int(big.sum())
    assert np.all(np.abs(c.points[:, 0] - 200) <= 30.5) and np.all(np.abs(c.points[:, 1] - 120) <= 30.5)
    assert np.array_equal(c.points, extract_contour(big, 100).points)
    # Two squares touching at a corner only are one 8-connected blob.
    d = np.zeros((20, 20), bool)
    d[2:6, 2:6] = True
    d[6:10, 6:10] = True
    cd = extract_contour(d, 50)
    assert cd.n_blobs == 1 and cd.area == 32


def test_holes_are_ignored():
    filled = ellipse_mask(160, 120, 50, 50)
    ring = filled & ~ellipse_mask(160, 120, 20, 20)
    cf, cr = extract_contour(filled, 200), extract_contour(ring, 200)
    assert cr.area == int(ring.sum()) < cf.area
    np.testing.assert_allclose(cr.points, cf.points, atol=1e-4)  # symmetric hole: same centroid
    assert cr.length == pytest.approx(cf.length)


def test_touches_border_flag():
    for sl in [np.s_[0:5, 50:60], np.s_[235:240, 50:60], np.s_[50:60, 0:5], np.s_[50:60, 315:320]]:
        m = np.zeros((H, W), bool)
        m[sl] = True
        assert extract_contour(m, 20).touches_border
    m = np.zeros((H, W), bool)
    m[1:239, 1:319] = True
    assert not extract_contour(m, 20).touches_border
    m[:] = False
    m[50:100, 50:100] = True  # the largest blob is inside ...
    m[0:3, 0:3] = True  # ... a small one touches the border
    c = extract_contour(m, 20)
    assert c.n_blobs == 2 and not c.touches_border


def test_border_blob_contour_runs_along_the_image_edge():
    m = np.zeros((30, 40), bool)
    m[0:10, 0:20] = True
    c = extract_contour(m, 60)
    assert c.points.min() >= 0.0 - 1e-6
    assert c.points[:, 0].max() == pytest.approx(19.0) and c.points[:, 1].max() == pytest.approx(9.0)
    assert c.length == pytest.approx(2 * (19 + 9))


def test_length_is_cv2_arclength_of_the_raw_boundary():
    m = figure_mask(True)
    found, _ = cv2.findContours(m.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    ref = cv2.arcLength(max(found, key=cv2.contourArea), closed=True)
    c = extract_contour(m, 200)
    assert c.length == pytest.approx(ref, rel=1e-9)
    # The resampled polygon cuts corners only slightly.
    p = c.points.astype(float)
    per = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum()
    assert 0.97 * ref <= per <= ref + 1e-3


def test_degenerate_blobs_give_finite_points():
    one = np.zeros((5, 5), bool)
    one[2, 3] = True
    c = extract_contour(one, 17)
    assert c.points.shape == (17, 2) and np.all(c.points == [3, 2])
    assert c.area == 1 and c.length == 0.0
    line = np.zeros((10, 12), bool)
    line[4, 2:9] = True  # horizontal, 1 px thin
    c = extract_contour(line, 10)
    assert np.all(np.isfinite(c.points)) and np.all(c.points[:, 1] == 4)
    assert c.points[:, 0].min() >= 2 and c.points[:, 0].max() <= 8
    diag = np.eye(8, dtype=np.uint8) * 255  # uint8 input, diagonal 8-connected line
    c = extract_contour(diag, 9)
    assert np.all(np.isfinite(c.points)) and c.n_blobs == 1 and c.area == 8


def test_empty_and_invalid_masks():
    with pytest.raises(EmptyMaskError):
        extract_contour(np.zeros((10, 10), bool))
    with pytest.raises(ValueError):
        extract_contour(np.zeros((2, 10, 10), bool))
    stack = np.stack([ellipse_mask(160, 120, 20, 30), np.zeros((H, W), bool)])
    with pytest.raises(EmptyMaskError, match="mask 1"):
        extract_contours(stack)


def test_extract_contours_stacks_single_results():
    masks = np.stack([figure_mask(False), figure_mask(True), ellipse_mask(100, 100, 30, 20)]).astype(np.uint8)
    out = extract_contours(masks, n_points=64)
    assert out["points"].shape == (3, 64, 2) and out["points"].dtype == np.float32
    assert out["area"].dtype == np.int32 and out["n_blobs"].dtype == np.int32
    assert out["length"].dtype == np.float32 and out["touches_border"].dtype == bool
    for k in range(3):
        c = extract_contour(masks[k], 64)
        np.testing.assert_array_equal(out["points"][k], c.points)
        assert out["area"][k] == c.area and out["n_blobs"][k] == c.n_blobs
        assert out["length"][k] == pytest.approx(c.length, rel=1e-6)


# ---------------------------------------------------------------- normalisation


def test_normalise_matches_brute_force_and_round_trips():
    rng = np.random.default_rng(7)
    pts = rng.normal(100.0, 30.0, size=(3, 4, 50, 2))
    q, c, s = normalise(pts)
    assert q.shape == pts.shape and c.shape == (3, 4, 2) and s.shape == (3, 4)
    for i in range(3):
        for j in range(4):
            p = pts[i, j]
            ref_c = p.sum(axis=0) / len(p)
            ref_s = np.sqrt(sum(float(np.dot(v - ref_c, v - ref_c)) for v in p) / len(p))
            np.testing.assert_allclose(c[i, j], ref_c, rtol=1e-12)
            assert s[i, j] == pytest.approx(ref_s, rel=1e-12)
    np.testing.assert_allclose(q.mean(axis=-2), 0, atol=1e-12)
    np.testing.assert_allclose(np.sqrt(np.mean(np.sum(q**2, -1), -1)), 1.0, rtol=1e-12)
    np.testing.assert_allclose(denormalise(q, c, s), pts, rtol=1e-12, atol=1e-9)
    q32, c32, s32 = normalise(pts.astype(np.float32))
    assert q32.dtype == c32.dtype == s32.dtype == np.float32


def test_normalise_degenerate_contour_gives_zeros_not_nan():
    pts = np.full((2, 10, 2), 5.0)
    pts[1] = np.linspace(0, 9, 20).reshape(10, 2)  # a regular one in the same batch
    q, c, s = normalise(pts)
    assert np.all(np.isfinite(q)) and s[0] == 0 and np.all(q[0] == 0) and s[1] > 0
    np.testing.assert_allclose(denormalise(q, c, s), pts, atol=1e-12)


def test_normalised_contour_invariant_to_translation_and_scale_of_the_mask():
    m = figure_mask(True)
    base = extract_contour(m, 200)
    qb, cb, sb = normalise(base.points.astype(np.float64))
    # Translation by whole pixels: exact.
    shifted = np.roll(m, (13, -21), axis=(0, 1))
    qs, cs, ss = normalise(extract_contour(shifted, 200).points.astype(np.float64))
    np.testing.assert_allclose(qs, qb, atol=1e-5)
    np.testing.assert_allclose(cs - cb, [-21, 13], atol=1e-4)
    assert ss == pytest.approx(sb, rel=1e-6)
    # 2x nearest-neighbour upscaling: the same shape up to pixel effects. The pixel-centre outline
    # sits 1/2 px inside the edge at either resolution (1/4 px after halving), and staircases of
    # thin parts scale unevenly, so points drift a little along the outline (measured: up to
    # 0.08 RMS radii for the thin-armed figure, 0.034 for an ellipse) while the curves coincide
    # more closely (0.035 and 0.010).
    for mask, curve_tol, point_max, point_mean in [
        (m, 0.05, 0.1, 0.04),
        (figure_mask(False), 0.05, 0.1, 0.05),
        (ellipse_mask(150.2, 110.7, 35, 50), 0.02, 0.05, 0.025),
    ]:
        q1, _, s1 = normalise(extract_contour(mask, 200).points.astype(np.float64))
        big = cv2.resize(mask.astype(np.uint8), (2 * W, 2 * H), interpolation=cv2.INTER_NEAREST)
        q2, _, s2 = normalise(extract_contour(big, 200).points.astype(np.float64))
        assert s2 / s1 == pytest.approx(2.0, rel=0.03)
        assert max(dist_to_polyline(q2, q1).max(), dist_to_polyline(q1, q2).max()) < curve_tol
        err = np.linalg.norm(q2 - q1, axis=-1)  # same index = same place on the body
        assert err.max() < point_max and err.mean() < point_mean


# ---------------------------------------------------------------- rasterisation


def test_draw_contour_square_matches_brute_force_boundary():
    sq = np.array([[3, 2], [12, 2], [12, 9], [3, 9]], float)
    img = draw_contour(sq, 15, 20)
    ref = np.zeros((15, 20), bool)
    ref[2, 3:13] = ref[9, 3:13] = True
    ref[2:10, 3] = ref[2:10, 12] = True
    np.testing.assert_array_equal(img, ref)


def test_draw_contour_subpixel_and_clipping():
    # Sub-pixel: a vertical segment at x = 5.4 lands in column 5, at x = 5.6 in column 6.
    for x, col in [(5.4, 5), (5.6, 6)]:
        img = draw_contour(np.array([[x, 1.0], [x, 8.0]]), 10, 10)
        assert np.array_equal(np.flatnonzero(img.any(axis=0)), [col])
    # Points far outside the image: clipped, no crash, the visible part drawn.
    img = draw_contour(np.array([[-1e7, 4.0], [1e7, 4.0]]), 10, 12)
    assert np.array_equal(np.flatnonzero(img.any(axis=1)), [4]) and img[4].all()
    assert not draw_contour(np.array([[-50.0, -50.0], [-40.0, -60.0], [-45.0, -30.0]]), 10, 10).any()
    with pytest.raises(ValueError):
        draw_contour(np.array([[np.nan, 1.0], [2.0, 3.0]]), 10, 10)


def test_drawn_contour_follows_the_mask_outline():
    m = figure_mask(True)
    c = extract_contour(m, 400)
    img = draw_contour(c.points, H, W)
    # Every drawn pixel is a mask pixel within one pixel of the background (the boundary band) ...
    eroded = cv2.erode(m.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    dilated = cv2.dilate(m.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    band = dilated & ~cv2.erode(eroded.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    assert np.all(band[img])
    # ... and the drawing is a closed curve: filling it recovers the mask up to the corner cuts.
    filled = np.zeros((H, W), np.uint8)
    cv2.fillPoly(filled, [np.round(c.points).astype(np.int32)], 1)
    assert (filled.astype(bool) ^ m).sum() < 0.05 * m.sum()


# ---------------------------------------------------------------- property test


@settings(max_examples=150, deadline=None, derandomize=True)
@given(
    arrays(np.bool_, st.tuples(st.integers(1, 12), st.integers(1, 12))),
    st.integers(1, 50),
)
def test_random_masks_never_nan(mask, n):
    if not mask.any():
        with pytest.raises(EmptyMaskError):
            extract_contour(mask, n)
        return
    c = extract_contour(mask, n)
    h, w = mask.shape
    assert c.points.shape == (n, 2) and np.all(np.isfinite(c.points))
    assert np.all(c.points >= 0) and np.all(c.points[:, 0] <= w - 1) and np.all(c.points[:, 1] <= h - 1)
    n_lab, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    counts = np.bincount(labels.ravel())[1:]
    assert c.n_blobs == n_lab - 1 and c.area == counts.max()
    # Brute-force choice: most pixels, then bounding box top, then its left, then centroid.
    keys = []
    for lab in np.flatnonzero(counts == counts.max()) + 1:
        yy, xx = np.nonzero(labels == lab)
        keys.append((yy.min(), xx.min(), yy.mean(), xx.mean(), lab))
    biggest = labels == min(keys)[-1]
    on_border = biggest[0].any() or biggest[-1].any() or biggest[:, 0].any() or biggest[:, -1].any()
    assert c.touches_border == on_border
    # Every resampled point lies on the blob's pixel hull: within sqrt(2)/2 of a blob pixel centre.
    ys, xs = np.nonzero(mask)
    d = np.min(np.hypot(c.points[:, None, 0] - xs, c.points[:, None, 1] - ys), axis=1)
    assert d.max() <= np.sqrt(2) / 2 + 1e-5
    # Orientation: densely resampled, the outline has the raw boundary's area with a positive sign
    # (clockwise on screen); coarse resamplings of thin blobs may legitimately self-cross.
    found, _ = cv2.findContours(
        cv2.copyMakeBorder(biggest.astype(np.uint8), 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0),
        cv2.RETR_EXTERNAL,
        cv2.CHAIN_APPROX_NONE,
    )
    raw_area = abs(cv2.contourArea(found[0]))
    dense = extract_contour(mask, 4000).points
    spacing = c.length / 4000
    assert signed_area(dense) == pytest.approx(raw_area, abs=len(found[0]) * spacing**2 + 1e-4)
    q, cen, s = normalise(c.points)
    assert np.all(np.isfinite(q)) and np.isfinite(s)


def test_single_blob_contour_gives_extract_contours_points_without_labelling():
    from silpose.shared.contours import single_blob_contour

    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(40):  # random smooth blobs, some touching the crop's edge, some with holes
        m = (cv2.GaussianBlur(rng.random((50, 40)).astype(np.float32), (0, 0), 3) > 0.5).astype(np.uint8)
        n, lab = cv2.connectedComponents(m, connectivity=8)
        for label in range(1, n):
            blob = (lab == label).astype(np.uint8)
            ref = extract_contour(blob, 64).points
            assert np.array_equal(single_blob_contour(blob, 64), ref)
            assert np.allclose(single_blob_contour(blob, 64, offset=(5, -2)), ref + (5, -2), atol=1e-4)
            # the label image itself (the other components in it too, 16-bit as the recordings' labelling)
            assert np.array_equal(single_blob_contour(lab.astype(np.uint16), 64, label=label), ref)
            checked += 1
    assert checked > 20
    with pytest.raises(EmptyMaskError):
        single_blob_contour(np.zeros((4, 4), np.uint8), 8)


def _start_by_loop(poly: np.ndarray, cx: float):
    """The farthest-up crossing of a closed polyline with x = cx, edge by edge in Python (first of ties); None
    without any."""
    best = None
    m = len(poly)
    for i in range(m):
        a, b = poly[i], poly[(i + 1) % m]
        if not min(a[0], b[0]) <= cx <= max(a[0], b[0]):
            continue
        p = (b if b[1] < a[1] else a) if a[0] == b[0] else a + (cx - a[0]) / (b[0] - a[0]) * (b - a)
        if best is None or p[1] < best[1][1]:
            best = (i, p)
    return best


def _resample_by_loop(poly: np.ndarray, edge: int, start: np.ndarray, n: int) -> np.ndarray:
    """Points k L / n along the closed polyline from ``start`` on edge ``edge``, walking segment by segment."""
    m = len(poly)
    path = [start] + [poly[(edge + 1 + k) % m] for k in range(m)] + [start]
    seg = [float(np.hypot(*(path[k + 1] - path[k]))) for k in range(len(path) - 1)]
    total = sum(seg)
    out, k, walked = [], 0, 0.0
    for t in (np.arange(n) * total / n if total > 0 else np.zeros(n)):
        while k < len(seg) - 1 and walked + seg[k] < t:
            walked += seg[k]
            k += 1
        f = 0.0 if seg[k] == 0 else (t - walked) / seg[k]
        out.append(path[k] + min(max(f, 0.0), 1.0) * (path[k + 1] - path[k]))
    return np.array(out)


def test_start_and_resampling_match_a_segment_by_segment_walk():
    from silpose.shared.contours import _start_on_polyline, resample_closed

    rng = np.random.default_rng(11)
    crossed = 0
    for trial in range(300):  # small integer polylines (vertical edges, lines through vertices) and smooth ones
        m = int(rng.integers(3, 30))
        poly = (rng.integers(0, 8, (m, 2)).astype(float) if trial % 2 else
                np.c_[np.cos(np.linspace(0, 2 * np.pi, m, endpoint=False)), np.sin(np.linspace(0, 2 * np.pi, m,
                      endpoint=False))] * rng.uniform(1, 50) + rng.normal(0, 0.3, (m, 2)))
        cx = float(rng.integers(0, 8)) if trial % 4 == 1 else float(rng.uniform(poly[:, 0].min(), poly[:, 0].max()))
        want = _start_by_loop(poly, cx)
        i, p = _start_on_polyline(poly, cx)
        if want is not None:
            crossed += 1
            assert i == want[0] and np.allclose(p, want[1], atol=1e-12)
        for n in (1, 7, 64):
            got = resample_closed(poly, i, p, n)
            assert np.allclose(got, _resample_by_loop(poly, i, p, n), atol=1e-9)
    assert crossed > 250


def test_compiled_outline_of_a_traced_chain_matches_the_segment_walk():
    """chain_outline (what tracing runs: OpenCV's chain read forwards or backwards, moved, started, resampled) against
    the reversal and offset done in numpy and the Python walks above; and the fallback without a crossing."""
    from silpose.shared.contour_kernels import chain_outline

    rng = np.random.default_rng(5)
    checked = 0
    for trial in range(60):
        m = (cv2.GaussianBlur(rng.random((40, 50)).astype(np.float32), (0, 0), 2.5) > 0.5).astype(np.uint8)
        found, _ = cv2.findContours(np.pad(m, 1), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        for raw in found:
            chain = raw.reshape(-1, 2)
            reverse, (ox, oy) = bool(trial % 2), rng.integers(-20, 20, 2)
            poly = (chain[::-1] if reverse else chain).astype(float) + (ox, oy)
            cx = float(rng.uniform(poly[:, 0].min(), poly[:, 0].max())) if trial % 3 else float(poly[0, 0])
            i, p = _start_by_loop(poly, cx)
            for n in (1, 5, 100):
                got = chain_outline(chain, reverse, float(ox), float(oy), cx, n)
                assert got.shape == (n, 2)
                assert np.allclose(got, _resample_by_loop(poly, i, p, n), atol=1e-9)
            checked += 1
    assert checked > 60
    # no crossing: the vertex nearest the line, topmost among ties (a line right of a vertical segment)
    seg = np.array([[3, 5], [3, 1], [2, 1], [2, 5]], np.int32)
    got = chain_outline(seg, False, 0.0, 0.0, 7.0, 4)
    assert np.array_equal(got[0], [3.0, 1.0])
