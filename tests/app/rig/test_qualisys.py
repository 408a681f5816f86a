"""Qualisys ``.qca.txt`` calibrations (Pose2Sim's demos): the axes convention checked on a camera written by
hand (a point straight ahead lands on the principal point, one above it higher in the image, one to the
world's right to the image's right), the known rig written in the format and imported back with the same
projections as cv2.projectPoints on the original calibration, and one-line errors naming file, camera and
attribute."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.app.rig.formats import detect_format, read_calibrations
from silpose.app.rig.importer import ImportOptions, import_rig
from silpose.app.rig.qualisys import write_qualisys
from silpose.shared.camera import RigError

#: One camera at (0, -3, 1) m looking along the world's +y, level, its Qualisys axes x = world x, y = world z
#: (up in the image), z = world -y (behind it); focal length 1000 px; the video window starts at (100, 50)
#: on the sensor, so the principal point (419.5, 289.5) on the sensor is (319.5, 239.5) in the image.
HAND_WRITTEN = """<?xml version='1.0' encoding='ASCII'?>
<QTM_Parameters_Ver_1.25>
 <calibration source="test.qca" type="regular">
  <cameras>
   <camera active="1" serial="front" viewrotation="0" model="Miqus Video">
    <fov_video left="100" top="50" right="739" bottom="529"/>
    <transform x="0" y="-3000" z="1000" r11="1" r12="0" r13="0" r21="0" r22="0" r23="1" r31="0" r32="-1" r33="0"/>
    <intrinsic focalLengthU="64000" focalLengthV="64000" centerPointU="26848" centerPointV="18528" skew="0"
               radialDistortion1="0" radialDistortion2="0" radialDistortion3="0"
               tangentalDistortion1="0" tangentalDistortion2="0"/>
   </camera>
   <camera active="0" serial="spare" viewrotation="0" model="Miqus M3"/>
  </cameras>
 </calibration>
</QTM_Parameters_Ver_1.25>
"""


def _pixels(cam, points_mm: np.ndarray) -> np.ndarray:
    """Undistorted pinhole pixels of world points (mm) through a CalibratedCamera, (N, 2)."""
    xc = points_mm @ np.asarray(cam.R).T + cam.t
    uvw = xc @ np.asarray(cam.K).T
    return uvw[:, :2] / uvw[:, 2:]


def test_hand_written_camera_axes_and_window(tmp_path):
    path = tmp_path / "Calib.qca.txt"
    path.write_text(HAND_WRITTEN)
    assert detect_format(path) == "qualisys"
    got = read_calibrations([path])
    assert [c.name for c in got.cameras] == ["front"]
    assert any("inactive camera(s) spare left out" in n for n in got.notes)
    cam = got.cameras[0]
    assert cam.size == (640, 480)
    ahead, above, right = _pixels(cam, np.array([[0.0, 0.0, 1000.0], [0.0, 0.0, 1300.0], [300.0, 0.0, 1000.0]]))
    np.testing.assert_allclose(ahead, [319.5, 239.5], atol=1e-9)
    np.testing.assert_allclose(above, [319.5, 239.5 - 1000.0 * 300 / 3000], atol=1e-9)
    np.testing.assert_allclose(right, [319.5 + 1000.0 * 300 / 3000, 239.5], atol=1e-9)


def test_round_trip_with_distortion(tmp_path, known_calibration, check_same_projections):
    path = write_qualisys(tmp_path / "lab.qca.txt", known_calibration)
    assert detect_format(path) == "qualisys"
    result = import_rig([path], ImportOptions(unit="mm", step=0.2))
    check_same_projections(result.rig, known_calibration)


def test_xml_told_apart_from_opencv_storage(tmp_path, known_calibration, spelled_writer):
    qtm = write_qualisys(tmp_path / "cameras.xml", known_calibration)
    opencv = tmp_path / "cam0.xml"
    spelled_writer(opencv, known_calibration[0], "opencv_sample")
    assert detect_format(qtm) == "qualisys" and detect_format(opencv) == "opencv"


@pytest.mark.parametrize("edit, pattern", [
    (lambda t: t.replace(' focalLengthU="64000"', "", 1), r"camera 'front': missing attribute intrinsic.focalLengthU"),
    (lambda t: t.replace('skew="0"', 'skew="3"', 1), r"camera 'front': attribute intrinsic.skew is not 0"),
    (lambda t: t.replace('r11="1"', 'r11="2"', 1), r"camera 'front': transform r11..r33: not a rotation matrix"),
    (lambda t: t.replace('x="0"', 'x="left"', 1), r"camera 'front': attribute transform.x: expected a number"),
    (lambda t: t.replace('active="1"', 'active="0"', 1), r"every camera is inactive"),
    (lambda t: t.replace("<cameras>", "<camera_list>").replace("</cameras>", "</camera_list>"), r"no <cameras>"),
    (lambda t: t.replace("</QTM_Parameters_Ver_1.25>", ""), r"not a readable XML file"),
])
def test_errors_name_file_camera_and_attribute(tmp_path, edit, pattern):
    path = tmp_path / "Calib.qca.txt"
    path.write_text(edit(HAND_WRITTEN))
    with pytest.raises(RigError, match=pattern) as err:
        read_calibrations([path])
    assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)
