"""``silpose rig show``'s camera rows: the person-height column against a direct projection, and a camera
whose lens model cannot see the workspace centre says so instead of printing NaN."""

from __future__ import annotations

import dataclasses

import numpy as np

from silpose.app.rig.show import camera_row
from silpose.shared.camera import default_rig


def _person_px(cam, rig) -> float:
    cx, cy = rig.workspace.center
    feet, head = cam.project(np.array([[cx, cy, 0.0], [cx, cy, 1.75]]))
    return float(np.hypot(*(head - feet)))


def test_person_column_matches_the_projection():
    rig = default_rig()
    for cam in rig:
        row = camera_row(cam, rig)
        assert row["1.75 m person at centre"] == f"{_person_px(cam, rig):.0f} px"


def test_a_camera_turned_away_or_beyond_its_lens_model_says_not_in_view():
    rig = default_rig()
    cam = rig.cameras[0]
    flip = np.diag([-1.0, 1.0, -1.0])  # half a turn about the camera's y axis: the centre is behind it
    away = dataclasses.replace(cam, R=flip @ cam.R, t=flip @ cam.t)
    assert np.all(away.to_camera(np.zeros((1, 3)))[:, 2] < 0)
    assert camera_row(away, rig)["1.75 m person at centre"] == "not in view"
    # a strong barrel term folds the lens model back before the centre's ray: project() gives NaN there
    turn = np.array([[np.cos(0.9), 0.0, np.sin(0.9)], [0.0, 1.0, 0.0], [-np.sin(0.9), 0.0, np.cos(0.9)]])
    aside = dataclasses.replace(cam, R=turn @ cam.R, t=turn @ cam.t, dist=np.array([-0.68, 0.0, 0.0, 0.0, 0.0]))
    assert np.all(aside.to_camera(np.zeros((1, 3)))[:, 2] > 0) and not np.isfinite(_person_px(aside, rig))
    assert camera_row(aside, rig)["1.75 m person at centre"] == "not in view"
