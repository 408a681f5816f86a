"""Skeletool / Captury ``.calibration`` files (MPI-INF-3DHP): the known rig, radial distortion only (the
format has no tangential terms), written in the format and imported back with the same projections as
cv2.projectPoints on the original calibration (``check_same_projections``); errors name file, camera, line."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.app.rig.formats import detect_format, read_calibrations
from silpose.app.rig.importer import ImportOptions, import_rig
from silpose.app.rig.skeletool import HEADER, write_skeletool
from silpose.shared.camera import RigError, load_rig


@pytest.fixture(scope="module")
def radial_calibration(known_calibration):
    """The known calibration with the tangential terms zeroed (k1, k2, k3 kept)."""
    out = []
    for c in known_calibration:
        d = np.asarray(c.dist, dtype=np.float64).copy()
        d[2:4] = 0.0
        out.append(type(c)(c.name, c.K, d, c.R, c.t, c.size, c.source))
    return out


def test_round_trip_with_radial_distortion(tmp_path, radial_calibration, check_same_projections):
    path = write_skeletool(tmp_path / "camera.calibration", radial_calibration)
    assert detect_format(path) == "skeletool"
    text = path.read_text()
    assert text.startswith(HEADER) and "  radial      3 " in text
    result = import_rig([path], ImportOptions(unit="mm", step=0.2))
    check_same_projections(result.rig, radial_calibration)
    with pytest.raises(RigError, match="a calibration file, not a silpose rig"):
        load_rig(path)


def test_header_decides_for_other_names_and_no_distortion(tmp_path, radial_calibration, check_same_projections):
    plain = [type(c)(c.name, c.K, np.zeros(5), c.R, c.t, c.size, c.source) for c in radial_calibration]
    path = write_skeletool(tmp_path / "cameras.txt", plain)
    assert detect_format(path) == "skeletool" and "  radial      0" in path.read_text()
    check_same_projections(import_rig([path], ImportOptions(unit="mm", step=0.2)).rig, plain)


@pytest.mark.parametrize("edit, pattern", [
    (lambda t: t.replace("animated    0", "animated    1", 1), r"camera 'cam0', line 5 \(animated\): an animated"),
    (lambda t: t.replace("  radial      3 ", "  radial      4 ", 1), r"line 8 \(radial\): expected the number of coef"),
    (lambda t: t.replace("  size        ", "  size        640 ", 1), r"line 4 \(size\): expected width and height"),
    (lambda t: t.replace("  sensor", "  lens", 1), r"line 3: unknown line 'lens'"),
    (lambda t: t.replace(HEADER, "Some other file", 1), r"line 1: expected 'Skeletool Camera Calibration File V1.0'"),
    (lambda t: "\n".join(l for l in t.splitlines() if not (l.startswith("  extrinsic") and "cam1" not in l)),
     r"camera 'cam0': missing line extrinsic"),
])
def test_errors_name_file_camera_and_line(tmp_path, radial_calibration, edit, pattern):
    path = write_skeletool(tmp_path / "camera.calibration", radial_calibration)
    path.write_text(edit(path.read_text()))
    with pytest.raises(RigError, match=pattern) as err:
        read_calibrations([path])
    assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)
