"""OpenCV <-> Blender camera conversion (pure maths, no Blender) and the raster filler."""

import numpy as np
import pytest

from silpose.datagen.blender.camera import BlenderCameraParams, from_blender, to_blender
from silpose.datagen.raster import (
    fill_triangles_cv2,
    fill_triangles_exact,
    fill_triangles_scanline,
    project_triangles,
)
from silpose.shared.camera import Camera, RigError, default_rig, look_at


def _random_camera(rng, name="c"):
    eye = rng.uniform(-8, 8, 3)
    eye[2] = rng.uniform(0.5, 4)
    R, t = look_at(eye, rng.uniform(-1, 1, 3))
    W, H = int(rng.integers(100, 800)), int(rng.integers(100, 600))
    f = rng.uniform(200, 900)
    K = np.array([[f, 0, rng.uniform(0.3, 0.7) * W], [0, f, rng.uniform(0.3, 0.7) * H], [0, 0, 1]])
    return Camera(name, K, R, t, W, H)


def test_round_trip_random_cameras():
    rng = np.random.default_rng(0)
    for _ in range(50):
        cam = _random_camera(rng)
        back = from_blender(to_blender(cam), name=cam.name)
        np.testing.assert_allclose(back.K, cam.K, atol=1e-9)
        np.testing.assert_allclose(back.R, cam.R, atol=1e-12)
        np.testing.assert_allclose(back.t, cam.t, atol=1e-9)


def test_documented_formulas_and_blender_axes():
    cam = default_rig()[1]
    p = to_blender(cam)
    W, H = cam.width, cam.height
    assert p.lens / p.sensor_width * W == pytest.approx(cam.K[0, 0])
    assert (W - 1) / 2 - p.shift_x * W == pytest.approx(cam.K[0, 2])
    assert (H - 1) / 2 + p.shift_y * W == pytest.approx(cam.K[1, 2])
    M = p.matrix_world
    np.testing.assert_allclose(M[:3, 3], cam.center, atol=1e-12)  # camera location
    # Blender cameras look down local -z with +y up: -z axis = OpenCV forward, +y = OpenCV up
    np.testing.assert_allclose(-M[:3, 2], cam.R[2], atol=1e-12)
    np.testing.assert_allclose(M[:3, 1], -cam.R[1], atol=1e-12)


def test_independent_blender_projection_matches_opencv():
    """Project like Blender does (camera-local -z, sensor-fit lens, shift) and compare."""
    rng = np.random.default_rng(1)
    for _ in range(10):
        cam = _random_camera(rng)
        p = to_blender(cam)
        X = cam.center + 5 * cam.R[2] + rng.normal(size=(20, 3))
        local = (np.linalg.inv(p.matrix_world) @ np.c_[X, np.ones(len(X))].T).T[:, :3]
        # Blender: the lens shift moves the frustum, so the image moves the other way; in image
        # widths from the image centre: x = lens / sensor_width * (x / -z) - shift_x
        u = p.lens / p.sensor_width * local[:, 0] / -local[:, 2] - p.shift_x
        v = p.lens / p.sensor_width * local[:, 1] / -local[:, 2] - p.shift_y
        # image-width units from the image centre, y up -> pixels with centres at integers
        px = np.c_[(p.width - 1) / 2 + u * p.width, (p.height - 1) / 2 - v * p.width]
        np.testing.assert_allclose(px, cam.project(X), atol=1e-8)


def test_blender_needs_square_pixels_and_no_distortion():
    cam = default_rig()[0]
    K = cam.K.copy()
    K[1, 1] *= 1.01
    with pytest.raises(RigError, match="fx == fy"):
        to_blender(Camera("odd", K, cam.R, cam.t, cam.width, cam.height))
    with pytest.raises(RigError, match="field dist"):
        to_blender(Camera("lens", cam.K, cam.R, cam.t, cam.width, cam.height, dist=[0.1, 0, 0, 0, 0]))
    with pytest.raises(RigError, match="field fisheye"):  # an equidistant fisheye: zero coefficients, still a fisheye
        to_blender(Camera("wide", cam.K, cam.R, cam.t, cam.width, cam.height, dist=[0, 0, 0, 0], fisheye=True))


def test_from_blender_ignores_object_scale():
    cam = default_rig()[2]
    p = to_blender(cam)
    M = p.matrix_world.copy()
    M[:3, :3] *= 2.0
    back = from_blender(BlenderCameraParams(p.lens, p.sensor_width, p.shift_x, p.shift_y, M, p.width, p.height))
    np.testing.assert_allclose(back.R, cam.R, atol=1e-12)


def _brute_force_fill(tri_px, H, W):
    """Per-pixel, per-triangle barycentric test (reference for the vectorised filler)."""
    mask = np.zeros((H, W), np.uint8)
    ys, xs = np.mgrid[0:H, 0:W]
    P = np.stack([xs.ravel(), ys.ravel()], 1).astype(float)
    for a, b, c in tri_px:
        T = np.array([b - a, c - a]).T
        if abs(np.linalg.det(T)) < 1e-12:
            continue
        lam = np.linalg.solve(T, (P - a).T).T
        inside = (lam[:, 0] >= -1e-12) & (lam[:, 1] >= -1e-12) & (lam.sum(1) <= 1 + 1e-12)
        mask.ravel()[inside] = 1
    return mask


def test_exact_filler_matches_brute_force():
    rng = np.random.default_rng(2)
    H, W = 40, 50
    tris = rng.uniform([-5, -5], [W + 5, H + 5], size=(30, 3, 2))
    small = rng.uniform(0, 1, size=(20, 1, 2)) * [W, H] + rng.normal(scale=2.0, size=(20, 3, 2))
    tris = np.concatenate([tris, small])
    ref = _brute_force_fill(tris, H, W)
    np.testing.assert_array_equal(fill_triangles_exact(tris, H, W), ref)
    np.testing.assert_array_equal(fill_triangles_scanline(tris, H, W), ref)


def test_fillers_agree_on_vertices_at_pixel_centres_and_degenerate_triangles():
    """Integer (tie) coordinates, horizontal edges, zero-area triangles, off-image triangles."""
    rng = np.random.default_rng(5)
    H, W = 30, 40
    tris = rng.integers(-3, 43, size=(200, 3, 2)).astype(float)
    tris[:20, 1, 1] = tris[:20, 0, 1]  # horizontal edges
    tris[20:30, 2] = tris[20:30, 1]  # zero area
    np.testing.assert_array_equal(fill_triangles_scanline(tris, H, W), fill_triangles_exact(tris, H, W))


def test_scanline_fills_several_images_at_once():
    rng = np.random.default_rng(6)
    H, W = 30, 40
    tris = rng.uniform(-5, 45, size=(3, 25, 3, 2))
    tris[1] += 100  # entirely off image 1
    stacked = fill_triangles_scanline(tris, H, W)
    assert stacked.shape == (3, H, W) and stacked[1].sum() == 0
    for k in range(3):
        np.testing.assert_array_equal(stacked[k], fill_triangles_exact(tris[k], H, W))


def test_cv2_filler_is_a_slightly_grown_version():
    rng = np.random.default_rng(3)
    H, W = 60, 60
    tris = rng.uniform(5, 55, size=(8, 3, 2))
    exact, cv = fill_triangles_exact(tris, H, W), fill_triangles_cv2(tris, H, W)
    assert np.all(cv >= exact)  # OpenCV also fills pixels its outline touches
    assert (cv.sum() - exact.sum()) < 0.3 * exact.sum()


def test_project_triangles_rejects_points_behind_camera():
    cam = default_rig()[0]
    V = np.array([cam.center - cam.R[2], cam.center + 3 * cam.R[2], cam.center + 3 * cam.R[2] + cam.R[0]])
    with pytest.raises(ValueError, match="behind the camera"):
        project_triangles(V, np.array([[0, 1, 2]]), cam)
