"""silpose.shared.rig_frame: the calibration->silpose similarity and the workspace rectangle."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from silpose.shared.rig_frame import Workspace, WorldTransform


def test_round_trip_and_camera_pose_agree_with_point_mapping():
    rng = np.random.default_rng(3)
    tr = WorldTransform(Rotation.random(random_state=4).as_matrix(), 0.001, [0.2, -1.0, 0.05])
    pts_c = rng.normal(scale=1500, size=(10, 3))  # millimetres
    np.testing.assert_allclose(tr.to_calibration(tr.to_silpose(pts_c)), pts_c, atol=1e-9)
    R = Rotation.random(random_state=5).as_matrix()
    t = rng.normal(scale=2000, size=3)
    R2, t2 = tr.camera_to_silpose(R, t)
    cam_c = pts_c @ R.T + t  # camera coordinates in mm
    cam_s = tr.to_silpose(pts_c) @ R2.T + t2  # in metres
    np.testing.assert_allclose(cam_s, cam_c * 0.001, atol=1e-9)
    assert WorldTransform.from_dict(tr.to_dict()).to_dict() == tr.to_dict()


@pytest.mark.parametrize("kwargs", [{"rotation": np.diag([1, 1, -1])}, {"scale": 0}, {"offset": [np.nan, 0, 0]}])
def test_bad_transforms(kwargs):
    with pytest.raises(ValueError):
        WorldTransform(**kwargs)


def test_workspace_bounds_contains_and_corners():
    ws = Workspace([1.0, 2.0], [2.0, 4.0])
    assert ws.bounds == ((0.0, 2.0), (0.0, 4.0))
    assert ws.contains(np.array([[0.0, 0.0], [2.0, 4.0], [2.01, 1.0]])).tolist() == [True, True, False]
    assert ws.corners(1.5)[:, 2].tolist() == [1.5] * 4
    with pytest.raises(ValueError):
        Workspace(size=[0.0, 1.0])
    assert Workspace.from_dict(ws.to_dict()).to_dict() == ws.to_dict()


def test_composition_applies_the_first_then_the_second():
    rng = np.random.default_rng(7)
    a = WorldTransform(Rotation.random(random_state=1).as_matrix(), 0.001, [1.0, 2.0, 3.0])
    b = WorldTransform(Rotation.random(random_state=2).as_matrix(), 2.5, [-0.5, 0.0, 0.25])
    X = rng.normal(scale=1000, size=(6, 3))
    np.testing.assert_allclose(a.followed_by(b).to_silpose(X), b.to_silpose(a.to_silpose(X)), rtol=1e-12, atol=1e-9)
    z_down = WorldTransform(np.diag([1.0, -1.0, -1.0]))
    assert z_down.up_in_calibration.tolist() == [0.0, 0.0, -1.0]
    assert WorldTransform().is_identity and not z_down.is_identity


def test_workspace_describe_and_default():
    assert Workspace().is_default and not Workspace(size=[3.0, 2.0]).is_default
    assert Workspace([0.5, -1.0], [2.2, 2.0]).describe() == "2.20 m x 2.00 m centred at (0.50, -1.00) m"
    with pytest.raises(ValueError, match="unknown"):
        Workspace.from_dict({"size": [1, 1], "centre": [0, 0]})
    with pytest.raises(ValueError, match="unknown"):
        WorldTransform.from_dict({"scale": 1, "origin": [0, 0, 0]})
    with pytest.raises(ValueError, match="scale"):
        WorldTransform(scale="abc")
