"""Tests of silpose.shared.camera against OpenCV and hand-written references."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from silpose.shared.camera import (
    Camera,
    Rig,
    RigError,
    default_rig,
    load_rig,
    look_at,
    ring_rig,
)
from silpose.shared.rig_frame import Workspace, WorldTransform

DIST = np.array([-0.21, 0.08, 0.0013, -0.0009, -0.012])


def random_points(rng, n=100):
    """(n, 3) points in the workspace volume, metres."""
    return rng.uniform([-1.5, -1.5, 0.0], [1.5, 1.5, 2.0], size=(n, 3))


def brown_conrady(cam: Camera, X: np.ndarray) -> np.ndarray:
    """Reference projection written from the OpenCV documentation's distortion model (k1 k2 p1 p2 k3)."""
    xc = X @ cam.R.T + cam.t
    x, y = xc[:, 0] / xc[:, 2], xc[:, 1] / xc[:, 2]
    k1, k2, p1, p2, k3 = cam.dist
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    K = cam.K
    return np.stack([K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=1)


def test_project_matches_opencv_without_distortion():
    rng = np.random.default_rng(0)
    X = random_points(rng)
    for cam in default_rig():
        rvec, _ = cv2.Rodrigues(cam.R)
        ref, _ = cv2.projectPoints(X, rvec, cam.t, cam.K, np.zeros(5))
        np.testing.assert_allclose(cam.project(X), ref.reshape(-1, 2), rtol=1e-10, atol=1e-9)
        # Leading dimensions are kept.
        assert cam.project(X.reshape(4, 25, 3)).shape == (4, 25, 2)
        # K_inv takes a pixel back to the ray OpenCV projected it from (normalised image coordinates)
        uv1 = np.c_[cam.project(X), np.ones(len(X))]
        cam_pts = cam.to_camera(X)
        np.testing.assert_allclose(uv1 @ cam.K_inv.T, cam_pts / cam_pts[:, 2:], rtol=1e-10, atol=1e-12)
        assert cam.K_inv is cam.K_inv  # computed once


def test_project_with_distortion_matches_opencv_and_the_written_out_model():
    rng = np.random.default_rng(1)
    X = random_points(rng)
    for c in default_rig():
        cam = Camera(c.name, c.K, c.R, c.t, c.width, c.height, dist=DIST)
        rvec, _ = cv2.Rodrigues(cam.R)
        ref, _ = cv2.projectPoints(X, rvec, cam.t, cam.K, DIST)
        got = cam.project(X)
        np.testing.assert_allclose(got, ref.reshape(-1, 2), rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(got, brown_conrady(cam, X), rtol=1e-10, atol=1e-8)
        assert np.abs(got - c.project(X)).max() > 1.0  # the distortion really acts


def test_project_no_points_with_distortion():
    """A frame where nobody was found projects (0, k, 3) points: cv2.projectPoints gives None for them."""
    c = default_rig()[0]
    cam = Camera(c.name, c.K, c.R, c.t, c.width, c.height, dist=DIST)
    assert cam.project(np.zeros((0, 3))).shape == (0, 2)
    assert cam.project(np.zeros((0, 4, 3))).shape == (0, 4, 2)


def test_rig_json_round_trip_is_exact(tmp_path):
    rig = ring_rig(n_cameras=3, azimuth_start_deg=12.3, focal_px=512.7)
    cams = list(rig.cameras)
    c = cams[1]
    cams[1] = Camera(c.name, c.K, c.R, c.t, c.width, c.height, dist=DIST)
    rig = Rig(tuple(cams))
    path = tmp_path / "rig.json"
    path.write_text(rig.to_json())
    for back in (Rig.from_json(rig.to_json()), load_rig(path)):
        assert back.names == rig.names
        for a, b in zip(rig, back):
            for f in ("K", "R", "t", "dist"):
                assert np.array_equal(getattr(a, f), getattr(b, f)), f
            assert (a.width, a.height) == (b.width, b.height)


def test_look_at_gives_a_rotation_pointing_at_the_target():
    rng = np.random.default_rng(2)
    for _ in range(20):
        eye = rng.uniform(-8, 8, 3)
        target = rng.uniform(-1, 1, 3)
        R, t = look_at(eye, target)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        forward = (target - eye) / np.linalg.norm(target - eye)
        np.testing.assert_allclose(R[2], forward, atol=1e-12)  # camera z axis in world coordinates
        np.testing.assert_allclose(-R.T @ t, eye, atol=1e-9)  # camera centre
        assert R[0, 2] == pytest.approx(0.0, abs=1e-12)  # no roll: the x axis stays horizontal
        assert R[1, 2] < 0  # image "down" points down in the world
        cam = Camera("c", np.array([[500, 0, 160], [0, 500, 120], [0, 0, 1.0]]), R, t, 320, 240)
        np.testing.assert_allclose(cam.project(target), [160, 120], atol=1e-9)
    with pytest.raises(RigError, match="parallel"):
        look_at((0, 0, 5), (0, 0, 0))


def test_default_rig_sees_the_workspace_45_degrees_apart_at_equal_height():
    rig = default_rig()
    assert len(rig) == 4 and rig.image_size == (320, 240)
    rig.check_sees_workspace()
    rig.check_sees_workspace(height=1.8)  # a standing person anywhere in the workspace
    centres = np.array([c.center for c in rig])
    np.testing.assert_allclose(centres[:, 2], centres[0, 2], atol=1e-9)
    az = np.degrees(np.arctan2(centres[:, 1], centres[:, 0]))
    np.testing.assert_allclose(np.diff(az), 45.0, atol=1e-9)
    # Every camera looks towards the workspace centre axis (it projects near the image centre).
    for cam in rig:
        px = cam.project(np.array([0.0, 0.0, 0.9]))
        np.testing.assert_allclose(px, [(cam.width - 1) / 2, (cam.height - 1) / 2], atol=1e-6)
    # A 1.75 m person at the centre spans a good part of the image height (docstring: ~115 px).
    h = [abs(np.diff(cam.project(np.array([[0, 0, 0], [0, 0, 1.75]]))[:, 1])[0]) for cam in rig]
    assert 100 < min(h) and max(h) < 130


def test_check_sees_workspace_names_the_camera_turned_away():
    rig = default_rig()
    cams = list(rig.cameras)
    c = cams[2]
    away = c.center + (c.center - np.array([0.0, 0.0, 0.9]))  # looking outwards, away from the workspace
    R, t = look_at(c.center, away)
    cams[2] = Camera(c.name, c.K, R, t, c.width, c.height)
    with pytest.raises(RigError, match="cam2"):
        Rig(tuple(cams)).check_sees_workspace()
    # Zoomed in so far that the corners fall outside the image.
    cams = list(rig.cameras)
    c = cams[1]
    cams[1] = Camera(c.name, c.K * np.array([[4, 1, 1], [1, 4, 1], [1, 1, 1]]), c.R, c.t, c.width, c.height)
    with pytest.raises(RigError, match=r"cam1.*workspace corner"):
        Rig(tuple(cams)).check_sees_workspace()


def test_workspace_error_teaches_the_convention_and_names_the_file(tmp_path):
    """Which camera, which corner, where it projects, what silpose assumes, what to do, which file."""
    path = tmp_path / "lab.json"
    path.write_text(Rig(default_rig().cameras, workspace=Workspace([4.0, 0.0], [3.0, 3.0])).to_json())
    rig = load_rig(path)
    with pytest.raises(RigError) as info:
        rig.check_sees_workspace(height=2.0)
    msg = str(info.value)
    assert msg.startswith(f"{path}: camera 'cam0' does not see the workspace corner [2.5, -1.5, 0.0] m")
    assert "projects to [" in msg and "in a 320x240 image" in msg
    for words in ("z up", "metres", "floor at z = 0", "3.00 m x 3.00 m centred at (4.00, 0.00) m",
                  "--up", "--origin", "silpose rig show"):
        assert words in msg, words
    assert "\n" not in msg
    rig.check_sees_workspace(height=2.0, workspace=Workspace())  # the default square is seen


def test_transform_workspace_and_source_round_trip_and_old_files_still_load(tmp_path):
    base = default_rig()
    assert base.to_dict().keys() == {"cameras"}  # the built-in rig's dict is unchanged (bit-identical datasets)
    tr = WorldTransform(np.diag([1.0, -1.0, -1.0]), 0.001, [-3.0, 4.0, 0.0])
    rig = Rig(base.cameras, tr, Workspace([0.5, -0.25], [2.2, 2.6]), source="cam0.xml, cam1.xml")
    path = tmp_path / "rig.json"
    path.write_text(rig.to_json())
    back = load_rig(path)
    assert back.source == str(path)  # errors name the file read
    assert Rig.from_dict(rig.to_dict()).source == "cam0.xml, cam1.xml"  # the stored provenance
    assert back.transform.to_dict() == tr.to_dict() and back.workspace.to_dict() == rig.workspace.to_dict()
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"cameras": base.to_dict()["cameras"]}))
    loaded = load_rig(old)
    assert loaded.transform.is_identity and loaded.workspace.is_default
    assert loaded.with_workspace(Workspace(size=[2.0, 2.0])).workspace.size.tolist() == [2.0, 2.0]


@pytest.mark.parametrize("change, words", [
    ({"transform": {"rotation": np.diag([1, 1, -1.0]).tolist()}}, "transform field rotation"),
    ({"transform": {"scale": -1}}, "transform field scale"),
    ({"workspace": {"size": [0, 2]}}, "workspace field size"),
    ({"workspace": {"center": [0, 0]}}, "workspace: expected an object with 'size'"),
    ({"workspace": {"size": [1, 1], "centre": [0, 0]}}, "workspace: unknown field(s) centre"),
    ({"cams": []}, "unknown field(s) cams"),
    ({"source": 3}, "field source"),
])
def test_bad_rig_frame_fields_name_the_file_and_field(tmp_path, change, words):
    d = {**default_rig().to_dict(), **change}
    path = tmp_path / "rig.json"
    path.write_text(json.dumps(d))
    with pytest.raises(RigError) as info:
        load_rig(path)
    assert str(info.value).startswith(f"{path}: ") and words in str(info.value), str(info.value)


@pytest.mark.parametrize("suffix", [".xml", ".yml", ".yaml", ".toml"])
def test_load_rig_sends_calibration_files_to_rig_import(tmp_path, suffix):
    path = tmp_path / f"cam1{suffix}"
    path.write_text("x")
    with pytest.raises(RigError, match=r"silpose rig import .*cam1" + suffix.replace(".", r"\.")):
        load_rig(path)


@pytest.mark.parametrize(
    "change, field",
    [
        (dict(R=np.diag([1.0, 1.0, 2.0])), "field R"),
        (dict(R=np.diag([1.0, 1.0, -1.0])), "field R"),  # a reflection is not a rotation
        (dict(K=np.eye(3)[:2]), "field K"),
        (dict(K=np.diag([-400.0, 400.0, 1.0])), "field K"),
        (dict(t=[0.0, np.nan, 5.0]), "field t"),
        (dict(t=[0.0, 5.0]), "field t"),
        (dict(R="abc"), "field R"),
        (dict(dist=[0.1, 0.2, 0.3]), "field dist"),
        (dict(width=320.0), "width"),
        (dict(height=0), "height"),
    ],
)
def test_bad_camera_fields_raise_rig_error_naming_the_field(change, field):
    base = dict(name="camX", K=np.diag([400.0, 400.0, 1.0]), R=np.eye(3), t=[0, 0, 5.0], width=320, height=240)
    base.update(change)
    with pytest.raises(RigError, match=field) as info:
        Camera(**base)
    assert "camX" in str(info.value)


def test_rig_errors():
    cam = default_rig()[0]
    with pytest.raises(RigError, match="no cameras"):
        Rig(())
    with pytest.raises(RigError, match="unique"):
        Rig((cam, cam))
    with pytest.raises(RigError, match="not valid JSON"):
        Rig.from_json("{nope")
    with pytest.raises(RigError, match="lacks field"):
        Rig.from_dict({"cameras": [{"name": "a"}]})
    with pytest.raises(RigError, match="not found"):
        load_rig("/nonexistent/rig.json")


def test_points_beyond_the_lens_models_fold_are_not_seen():
    """A real calibration's k2 = -1.61 folds OpenCV's radial model back at r = 0.59: cv2.projectPoints puts a point
    43 deg off-axis (image right edge 31 deg) inside the image; Camera.project calls it not seen (NaN). The fold radius is the
    first root of d/dr [r (1 + k1 r^2 + k2 r^4)] = 1 + 3 k1 r^2 + 5 k2 r^4 (numpy.roots)."""
    import cv2

    from silpose.shared.pinhole import Camera as PinholeCamera

    K = np.array([[1583.0, 0, 970.4], [0, 1589.7, 523.9], [0, 0, 1]])
    dist = np.array([0.005225, -1.613793, -0.005377, -0.000435, 0.0])
    cam = PinholeCamera("c", K, np.eye(3), np.zeros(3), 1920, 1080, dist)
    roots = np.roots([5 * dist[1], 0, 3 * dist[0], 0, 1])
    fold = min(r.real for r in roots if abs(r.imag) < 1e-12 and r.real > 0)
    assert cam.max_radius == pytest.approx(fold, abs=2e-3)
    far = np.array([[0.9, 0.2, 1.0], [0.2, 0.1, 1.0]])  # r = 0.92 (beyond the fold; 43 deg off-axis) and r = 0.22
    folded, _ = cv2.projectPoints(far, np.zeros(3), np.zeros(3), K, dist)
    assert cam.in_image(folded.reshape(-1, 2))[0]  # OpenCV alone: "in the image"
    px = cam.project(far)
    assert np.isnan(px[0]).all() and not cam.in_image(px)[0]
    np.testing.assert_allclose(px[1], folded.reshape(-1, 2)[1], atol=1e-9)  # inside the domain: unchanged
    assert PinholeCamera("d", K, np.eye(3), np.zeros(3), 1920, 1080).max_radius == np.inf
