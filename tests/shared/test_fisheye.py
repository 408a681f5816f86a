"""Fisheye lenses (``Camera.fisheye``): OpenCV's fisheye model against the model written out here from OpenCV's
``cv::fisheye`` documentation, its inverse, its domain, and the rig file."""

from __future__ import annotations

import json

import numpy as np
import pytest

from silpose.shared.camera import Camera, Rig, RigError, default_rig

K = np.array([[620.0, 0.0, 959.5], [0.0, 615.0, 539.5], [0.0, 0.0, 1.0]])
#: a GoPro-like wide lens (anipose calibrates such lenses with ``fisheye = true``)
D = np.array([0.041, -0.012, 0.0031, -0.0004])


def fisheye_reference(K: np.ndarray, d: np.ndarray, xc: np.ndarray) -> np.ndarray:
    """Camera-frame points (N, 3) -> pixels, written from OpenCV's fisheye documentation: a = x/z, b = y/z,
    r^2 = a^2 + b^2, theta = atan(r), theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
    x' = (theta_d / r) a, y' = (theta_d / r) b, u = fx x' + cx, v = fy y' + cy."""
    a, b = xc[:, 0] / xc[:, 2], xc[:, 1] / xc[:, 2]
    r = np.hypot(a, b)
    theta = np.arctan(r)
    t2 = theta ** 2
    theta_d = theta * (1 + d[0] * t2 + d[1] * t2 ** 2 + d[2] * t2 ** 3 + d[3] * t2 ** 4)
    scale = np.where(r > 0, theta_d / np.where(r > 0, r, 1.0), 1.0)
    return np.stack([K[0, 0] * scale * a + K[0, 2], K[1, 1] * scale * b + K[1, 2]], axis=1)


def _camera(dist=D, **kw) -> Camera:
    c = default_rig()[1]
    return Camera("gopro", K, c.R, c.t, 1920, 1080, dist, fisheye=True, **kw)


def test_projection_matches_the_written_out_model_and_normalised_inverts_it():
    cam = _camera()
    rng = np.random.default_rng(0)
    X = cam.center + rng.normal(0, 1, (500, 3)) * 4.0
    xc = cam.to_camera(X)
    front = xc[:, 2] > 0.05
    got = cam.project(X)
    assert np.abs(got[front] - fisheye_reference(K, D, xc[front])).max() < 1e-6
    assert np.isnan(got[xc[:, 2] < 0]).all()  # behind the lens: not seen
    # a ray 65 degrees off the axis is in the image, beyond where the same K as a pinhole reaches
    wide = np.array([[np.tan(np.radians(65.0)), 0.0, 1.0]])
    u = fisheye_reference(K, D, wide)[0, 0]
    assert 0 < u < 1920 and K[0, 0] * wide[0, 0] + K[0, 2] > 1920
    off_axis = np.degrees(np.arctan2(np.hypot(xc[:, 0], xc[:, 1]), xc[:, 2]))
    seen = front & cam.in_image(got) & (off_axis < 80)  # OpenCV's iterative inverse loses digits towards 90 deg
    assert seen.sum() > 100 and off_axis[seen].max() > 70
    n = cam.normalised(got[seen])
    assert np.abs(n - xc[seen, :2] / xc[seen, 2:3]).max() < 1e-6
    # the standard model is another lens: the same coefficients as (k1, k2, p1, p2) project elsewhere
    pinhole = Camera("p", K, cam.R, cam.t, 1920, 1080, D)
    assert np.nanmedian(np.abs(pinhole.project(X[seen]) - got[seen])) > 5.0


def test_the_domain_ends_where_the_polynomial_turns_back():
    d = np.array([-0.25, 0.0, 0.0, 0.0])  # theta_d = theta - 0.25 theta^3 peaks at theta = sqrt(4 / 3) < pi / 2
    cam = _camera(d)
    peak = np.sqrt(1 / (3 * 0.25))
    assert cam.max_radius == pytest.approx(np.tan(peak), rel=1e-3)
    def world(theta):  # the world point 1 m along the camera ray theta off the axis
        return (np.array([[np.sin(theta), 0.0, np.cos(theta)]]) - cam.t) @ cam.R

    assert np.isfinite(cam.project(world(0.9 * peak))).all()
    assert np.isnan(cam.project(world(1.1 * peak))).all()
    assert _camera().max_radius == np.inf  # D grows up to 90 degrees: every point in front is seen


def test_rig_files_carry_the_lens_and_older_files_read_as_before():
    rig = Rig((_camera(), default_rig()[0]))
    d = json.loads(rig.to_json())
    assert d["cameras"][0]["fisheye"] is True and "fisheye" not in d["cameras"][1]
    back = Rig.from_json(rig.to_json())
    assert back[0].fisheye and not back[1].fisheye
    X = np.random.default_rng(1).uniform(-1, 1, (50, 3)) + [0, 0, 1]
    assert np.array_equal(back[0].project(X), rig[0].project(X), equal_nan=True)
    assert default_rig().to_json() == Rig.from_json(default_rig().to_json()).to_json()


@pytest.mark.parametrize("change, message", [
    (dict(dist=[0.1, 0.0, 0.0, 0.0, 0.0]), "a fisheye lens has 4 coefficients"),
    (dict(fisheye="yes"), "field fisheye: expected true or false"),
])
def test_bad_lenses_are_one_line_errors(change, message):
    d = json.loads(Rig((_camera(),)).to_json())
    d["cameras"][0].update(change)
    with pytest.raises(RigError, match=message):
        Rig.from_dict(d, "rig.json")


def test_a_dataset_of_fisheye_cameras_says_so_and_reads_back():
    """The shards' metadata: the camera frame convention names the fisheye model only when a camera has it,
    and the rig read back from the metadata projects as the one written."""
    from silpose.shared.dataset_schema import DEFAULT_CONVENTIONS, build_metadata, rig_from_metadata

    rig = Rig((_camera(), default_rig()[0]))
    meta = build_metadata(rig.to_dict()["cameras"], {}, 64, generator_version="test")
    assert "fisheye" in meta["conventions"]["camera_frame"]
    plain = build_metadata(default_rig().to_dict()["cameras"], {}, 64, generator_version="test")
    assert plain["conventions"]["camera_frame"] == DEFAULT_CONVENTIONS["camera_frame"]
    back = rig_from_metadata(json.loads(json.dumps(meta)))
    X = np.random.default_rng(2).uniform(-1, 1, (20, 3)) + [0, 0, 1]
    assert back[0].fisheye and np.array_equal(back[0].project(X), rig[0].project(X), equal_nan=True)
