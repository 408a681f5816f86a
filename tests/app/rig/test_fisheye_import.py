"""Fisheye calibrations (anipose's ``fisheye = true``, COLMAP's ``OPENCV_FISHEYE``): the known rig given fisheye
lenses, written in each format and imported back, projects calibration-frame points as OpenCV's fisheye model,
written out in ``tests/shared/test_fisheye.py``, does on the original calibration; the automatic workspace of
such a rig; one-line errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from silpose.app.rig.colmap import write_colmap
from silpose.app.rig.importer import ImportOptions, import_rig
from silpose.app.rig.pose2sim import write_pose2sim
from silpose.shared.camera import RigError
from tests.shared.test_fisheye import fisheye_reference

LENSES = np.array([[0.041, -0.012, 0.0031, -0.0004], [0.02, 0.004, -0.001, 0.0], [-0.01, 0.03, -0.02, 0.004],
                   [0.06, -0.02, 0.0, 0.0]])


@pytest.fixture()
def fisheye_calibration(known_calibration):
    return [dataclasses.replace(c, dist=LENSES[i % len(LENSES)].copy(), fisheye=True)
            for i, c in enumerate(known_calibration)]


def _check(rig, calibration, lab_frame):
    assert rig.names == tuple(c.name for c in calibration) and all(cam.fisheye for cam in rig)
    X = np.random.default_rng(0).uniform([-1.5, -1.5, 0.0], [1.5, 1.5, 2.0], size=(200, 3))
    P = lab_frame.to_calibration(X)
    for cam, ref in zip(rig, calibration):
        xc = P @ np.asarray(ref.R).T + ref.t
        got = cam.project(rig.transform.to_silpose(P))
        assert np.abs(got - fisheye_reference(ref.K, ref.dist, xc)).max() < 1e-6


def test_anipose_toml(tmp_path, fisheye_calibration, lab_frame):
    toml = write_pose2sim(tmp_path / "calibration.toml", fisheye_calibration)
    assert toml.read_text().count("fisheye = true") == len(fisheye_calibration)
    result = import_rig([toml], ImportOptions(unit="mm", step=0.2))
    _check(result.rig, fisheye_calibration, lab_frame)
    ws = result.rig.workspace
    assert ws.size[0] > 1.0 and ws.size[1] > 1.0  # the automatic workspace, through the fisheye projection


@pytest.mark.parametrize("binary", [False, True], ids=["text", "binary"])
def test_colmap_opencv_fisheye(tmp_path, fisheye_calibration, lab_frame, binary):
    cameras, images = write_colmap(tmp_path / "sparse", fisheye_calibration, binary=binary)
    if not binary:
        assert " OPENCV_FISHEYE " in cameras.read_text()
    result = import_rig([images if binary else cameras], ImportOptions(unit="mm", step=0.2))
    _check(result.rig, fisheye_calibration, lab_frame)


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace("fisheye = true", 'fisheye = "yes"', 1), r"field cam_01\.fisheye: expected true or false"),
    (lambda t: t.replace("distortions = [ ", "distortions = [ 0.0, ", 1),
     r"field cam_01\.distortions: a fisheye camera has 4 coefficients \(k1, k2, k3, k4\), got 5"),
])
def test_errors_name_the_file_and_field(tmp_path, fisheye_calibration, edit, message):
    toml = write_pose2sim(tmp_path / "calibration.toml", fisheye_calibration)
    toml.write_text(edit(toml.read_text()))
    with pytest.raises(RigError, match=f"^{toml}: " + message):
        import_rig([toml], ImportOptions(unit="mm", step=0.2))
