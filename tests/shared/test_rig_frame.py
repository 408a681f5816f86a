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
