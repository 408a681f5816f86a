"""Joints fitted to the silhouettes of the views used (``silpose.app.recordings.silhouette_fit``).

The signed distance is checked against OpenCV's ``pointPolygonTest``; the fit on a box-shaped "body" seen by the
lab rig's cameras, whose outlines are the images of the box (its projected corners' convex hull).
"""

import cv2
import numpy as np
import pytest

from silpose.app.recordings.silhouette_fit import (MARGIN_M, fit_to_silhouettes, inside_far_from_outline, joint_margins,
                                                 signed_distance)
from silpose.datagen.lab import lab_rig
from silpose.shared.skeleton import JOINT_INDEX, N_JOINTS, TERMINAL_JOINTS


def _star(rng, n=60, centre=(100.0, 80.0)):
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    rad = rng.uniform(20, 60, n)
    return np.stack([centre[0] + rad * np.cos(ang), centre[1] + rad * np.sin(ang)], axis=1)


def test_signed_distance_matches_opencv():
    rng = np.random.default_rng(0)
    polys = np.stack([_star(rng) for _ in range(5)])  # (B, n, 2)
    pts = rng.uniform([20, 0], [180, 160], size=(5, 300, 2))
    s, near = signed_distance(pts, polys)
    for b in range(5):
        contour = polys[b].astype(np.float32).reshape(-1, 1, 2)
        ref = np.array([cv2.pointPolygonTest(contour, (float(x), float(y)), True) for x, y in pts[b]])
        on_edge = np.abs(ref) < 1e-3
        assert np.allclose(-s[b][~on_edge], ref[~on_edge], atol=1e-3)  # OpenCV: positive inside
        assert np.allclose(np.linalg.norm(pts[b] - near[b], axis=1), np.abs(s[b]), atol=1e-9)
    assert (s < 0).any() and (s > 0).any()


BOX = np.array([[x, y, z] for x in (-0.2, 0.2) for y in (-0.15, 0.15) for z in (0.0, 1.7)])


def _outlines(cameras, box=BOX, n=120):
    """(1, K, n, 2) px: each camera's image of ``box`` (the convex hull of its projected corners), resampled."""
    out = []
    for cam in cameras:
        hull = cv2.convexHull(cam.project(box).astype(np.float32)).reshape(-1, 2).astype(float)
        closed = np.vstack([hull, hull[:1]])
        seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
        at = np.linspace(0, seg.sum(), n, endpoint=False)
        cum = np.r_[0, np.cumsum(seg)]
        out.append(np.stack([np.interp(at, cum, closed[:, 0]), np.interp(at, cum, closed[:, 1])], axis=1))
    return np.stack(out)[None]


def _inside_by(cameras, outlines, used, x):
    """(K,) px: how far inside each used outline the point x (3,) projects (negative: outside)."""
    return np.array([-signed_distance(cam.project(x[None])[None], outlines[0, k][None])[0][0, 0]
                     for k, cam in enumerate(cameras) if used[0, k]])


def test_a_joint_beside_the_body_moves_inside_every_used_outline_and_one_inside_stays():
    cams = list(lab_rig())
    outlines = _outlines(cams)
    used = np.ones((1, len(cams)), bool)
    joints = np.zeros((1, N_JOINTS, 3))
    joints[0, :, 2] = 1.0  # every joint at the body's centre, 1 m up
    wrist = JOINT_INDEX["l_elbow"]  # not terminal: it gets the margin
    joints[0, wrist] = [0.35, 0.0, 1.0]  # 15 cm beside the box
    std = np.full((1, N_JOINTS, 3), 0.3)
    fitted = fit_to_silhouettes(joints, std, outlines, used, cams)
    moved = np.linalg.norm(fitted - joints, axis=2)[0]
    assert np.all(moved[np.arange(N_JOINTS) != wrist] == 0.0)  # inside every outline by far more than the margin
    assert _inside_by(cams, outlines, used, joints[0, wrist]).min() < 0  # it was outside some outline
    margin_px = MARGIN_M * cams[0].K[0, 0] / 6.0  # the margin at the box's depth, at least ~6 m from every camera
    assert _inside_by(cams, outlines, used, fitted[0, wrist]).min() > 0.5 * margin_px
    assert 0.1 < moved[wrist] < 0.2  # about the 15 cm it was out, not to the middle of the body


def test_the_prior_holds_a_certain_joint_and_unused_views_do_not_count():
    cams = list(lab_rig())
    outlines = _outlines(cams)
    joints = np.zeros((1, N_JOINTS, 3))
    joints[0, :, 2] = 1.0
    j = JOINT_INDEX["r_knee"]
    joints[0, j] = [0.3, 0.0, 0.5]
    loose = fit_to_silhouettes(joints, np.full((1, N_JOINTS, 3), 0.3), outlines, np.ones((1, 4), bool), cams)
    tight = fit_to_silhouettes(joints, np.full((1, N_JOINTS, 3), 0.02), outlines, np.ones((1, 4), bool), cams)
    move = lambda f: float(np.linalg.norm(f[0, j] - joints[0, j]))  # noqa: E731
    assert move(tight) < move(loose) - 0.01  # a certain joint gives way less (measured: 8.1 vs 10.0 cm)
    # an outline far away in an unused view changes nothing; no used view at all: nothing moves
    far = outlines.copy()
    far[0, 2] += 500.0
    used = np.array([[True, True, False, True]])
    assert np.array_equal(fit_to_silhouettes(joints, np.full((1, N_JOINTS, 3), 0.3), far, used, cams),
                          fit_to_silhouettes(joints, np.full((1, N_JOINTS, 3), 0.3), outlines, used, cams))
    none = fit_to_silhouettes(joints, np.full((1, N_JOINTS, 3), 0.3), outlines, np.zeros((1, 4), bool), cams)
    assert np.array_equal(none, joints)


@pytest.mark.parametrize("bad", ["nan_joints", "nan_outline"])
def test_rows_it_cannot_fit_are_left_alone(bad):
    cams = list(lab_rig())
    outlines = _outlines(cams)
    joints = np.zeros((1, N_JOINTS, 3))
    joints[0, :, 0] = 0.5  # every joint beside the box
    joints[0, :, 2] = 1.0
    used = np.ones((1, 4), bool)
    if bad == "nan_joints":
        joints[0, 3] = np.nan
        out = fit_to_silhouettes(joints, np.full((1, N_JOINTS, 3), 0.3), outlines, used, cams)
        assert np.array_equal(out, joints, equal_nan=True)
    else:
        outlines[0, 1] = np.nan  # a used view whose outline is missing counts as unused
        out = fit_to_silhouettes(joints, np.full((1, N_JOINTS, 3), 0.3), outlines, used, cams)
        assert np.isfinite(out).all() and not np.array_equal(out, joints)


def test_terminal_joints_lie_on_the_surface_the_others_inside_it():
    m = joint_margins()
    assert m.shape == (N_JOINTS,)
    assert all(m[j] == 0 for j in TERMINAL_JOINTS) and all(m[j] == MARGIN_M for j in range(N_JOINTS)
                                                           if j not in TERMINAL_JOINTS)


def test_the_screen_only_settles_points_inside_by_more_than_the_margin():
    rng = np.random.default_rng(1)
    ang = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    polys = []
    for _ in range(4):  # smooth outlines of short, even edges, as the contours are (arc-length resampled)
        a, b = rng.uniform(5, 15, 2)
        rad = 45 + a * np.sin(3 * ang + rng.uniform(0, 6)) + b * np.cos(5 * ang)
        polys.append(np.stack([100 + rad * np.cos(ang), 80 + rad * np.sin(ang)], axis=1))
    polys = np.stack(polys)
    pts = rng.uniform([20, 0], [180, 160], size=(4, 400, 2))
    margin = rng.uniform(0, 6, size=(4, 400))
    settled = inside_far_from_outline(pts, polys, margin)
    s, _ = signed_distance(pts, polys)
    assert settled.sum() > 100  # it settles many
    assert np.all(s[settled] < -margin[settled])  # and never one within the margin of the outline, or outside
