"""COLMAP sparse models (``cameras`` + ``images``, text and binary): the known rig written as a model and imported
back with the same projections as cv2.projectPoints on the original calibration (``check_same_projections``);
the conventions (principal point 0.5 px, scalar-first quaternion, world -> camera) checked on hand-written files
against scipy, not against silpose's writer; frames of fixed cameras; one-line errors naming the file."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from silpose.app.rig.colmap import write_colmap
from silpose.app.rig.formats import detect_format, read_calibrations
from silpose.app.rig.importer import ImportOptions, import_rig
from silpose.shared.camera import Camera, RigError


def _with_dist(calibration, how: str):
    out = []
    for c in calibration:
        d = np.asarray(c.dist, dtype=np.float64).copy()
        if how == "opencv":
            d[4] = 0.0  # no k3: the OPENCV model
        elif how == "none":
            d[:] = 0.0
        out.append(dataclasses.replace(c, dist=d))
    return out


@pytest.mark.parametrize("binary", [False, True], ids=["text", "binary"])
@pytest.mark.parametrize("how, model", [("full", "FULL_OPENCV"), ("opencv", "OPENCV"), ("none", "PINHOLE")])
def test_round_trip(tmp_path, known_calibration, check_same_projections, binary, how, model):
    calibration = _with_dist(known_calibration, how)
    cameras, images = write_colmap(tmp_path / "sparse" / "0", calibration, binary=binary)
    if not binary:
        assert f" {model} " in cameras.read_text()
    result = import_rig([images if binary else cameras], ImportOptions(unit="mm", step=0.2))
    check_same_projections(result.rig, calibration)
    assert any("unit and floor are arbitrary" in n and "--unit" in n and "--floor-offset" in n for n in result.notes)


IMAGES_HEADER = ("# Image list with two lines of data per image:\n"
                 "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
                 "#   POINTS2D[] as (X, Y, POINT3D_ID)\n")
Q = (0.7, 0.1, -0.5, 0.5)  # QW QX QY QZ, a unit quaternion (0.49 + 0.01 + 0.25 + 0.25 = 1)


@pytest.mark.parametrize("points", ["empty", "keypoints", "missing"])
def test_conventions_against_scipy_and_by_hand(tmp_path, points):
    (tmp_path / "cameras.txt").write_text(
        "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
        "1 PINHOLE 640 480 500 510 320 240\n"
        "2 SIMPLE_RADIAL 800 600 700 400.25 299.75 -0.05\n")
    second = {"empty": ["", ""], "keypoints": ["12.5 30.25 7 100 200 -1", "5 6 -1"], "missing": None}[points]
    lines = [f"3 {' '.join(map(str, Q))} 0.1 -0.2 4.0 1 a.png", "1 1 0 0 0 0 0 5 2 b.png"]
    if second is not None:
        lines = [lines[0], second[0], lines[1], second[1]]
    (tmp_path / "images.txt").write_text(IMAGES_HEADER + "\n".join(lines) + "\n")
    read = read_calibrations([tmp_path / "images.txt"])
    b, a = read.cameras  # in IMAGE_ID order
    assert (a.name, b.name) == ("a", "b") and a.size == (640, 480) and b.size == (800, 600)
    np.testing.assert_array_equal(a.K, [[500, 0, 319.5], [0, 510, 239.5], [0, 0, 1]])  # COLMAP cx, cy - 0.5
    np.testing.assert_array_equal(b.K, [[700, 0, 399.75], [0, 700, 299.25], [0, 0, 1]])
    np.testing.assert_array_equal(b.dist, [-0.05, 0, 0, 0, 0])
    R_ref = Rotation.from_quat([Q[1], Q[2], Q[3], Q[0]]).as_matrix()  # scipy is scalar-last
    np.testing.assert_allclose(a.R, R_ref, atol=1e-15)
    np.testing.assert_array_equal(a.t, [0.1, -0.2, 4.0])
    X = np.array([0.3, -0.4, 0.5])
    xc = R_ref @ X + [0.1, -0.2, 4.0]  # x_cam = R X + T
    by_hand = [500 * xc[0] / xc[2] + 320 - 0.5, 510 * xc[1] / xc[2] + 240 - 0.5]
    cam = Camera(a.name, a.K, a.R, a.t, 640, 480, a.dist)
    np.testing.assert_allclose(cam.project(X[None])[0], by_hand, atol=1e-9)


def test_frames_of_fixed_cameras_are_read_once(tmp_path, known_calibration, check_same_projections):
    cameras, images = write_colmap(tmp_path, known_calibration, frames=3)
    assert "cam0/frame0003.jpg" in images.read_text()
    result = import_rig([cameras], ImportOptions(unit="mm", step=0.2))
    check_same_projections(result.rig, known_calibration)
    assert any("several frames each" in n and "read once" in n for n in result.notes)


def test_a_moved_camera_or_other_intrinsics_is_an_error(tmp_path, known_calibration):
    cameras, images = write_colmap(tmp_path, known_calibration, frames=2)
    text = images.read_text()
    lines = text.splitlines()
    i = next(k for k, line in enumerate(lines) if line.endswith("cam1/frame0002.jpg"))
    words = lines[i].split()
    words[5] = repr(float(words[5]) + 30.0)  # TX: 30 mm away
    lines[i] = " ".join(words)
    images.write_text("\n".join(lines) + "\n")
    with pytest.raises(RigError, match=rf"line {i + 1}: image 'cam1/frame0002.jpg' of camera 'cam1' is .* the camera "
                                       r"moved; silpose needs fixed cameras") as err:
        read_calibrations([images])
    assert str(err.value).startswith(str(images)) and "\n" not in str(err.value)
    # the second frame of cam1 on a camera of its own with another focal length
    words = text.splitlines()[i].split()
    words[8] = "9"
    images.write_text(text.replace(text.splitlines()[i], " ".join(words)))
    cam_line = next(line for line in cameras.read_text().splitlines() if line.startswith("2 "))
    fx = cam_line.split()[4]
    cameras.write_text(cameras.read_text() + cam_line.replace("2 ", "9 ", 1).replace(f" {fx} ", " 321.0 ", 1) + "\n")
    with pytest.raises(RigError, match=r"has other intrinsics \(CAMERA_ID 9\)"):
        read_calibrations([images])
    cameras.write_text(cameras.read_text().replace(" 321.0 ", f" {fx} "))  # equal parameters: one camera
    assert len(read_calibrations([images]).cameras) == len(known_calibration)


def _edit_line(path, starts: str, edit) -> None:
    lines = path.read_text().splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith(starts))
    lines[i] = edit(lines[i])
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("case, pattern", [
    ("fisheye", r"cameras\.txt: line 5: camera 2 \(of image 'cam1\.jpg'\): model THIN_PRISM_FISHEYE is a non-OpenCV .*"
                r"colmap image_undistorter"),
    ("unknown camera", r"images\.txt: line 7: image 'cam1\.jpg': CAMERA_ID 42 is not a camera of .*cameras\.txt"),
    ("param count", r"cameras\.txt: line 4: camera 1: model FULL_OPENCV has 12 parameters .*, got 11"),
    ("truncated cameras.bin", r"cameras\.bin: truncated"),
    ("truncated images.bin", r"images\.bin: truncated"),
])
def test_errors_name_the_file(tmp_path, known_calibration, case, pattern):
    cameras, images = write_colmap(tmp_path, _with_dist(known_calibration, "full"), binary="bin" in case)
    if case == "fisheye":  # a model silpose does not read (OPENCV_FISHEYE it does: test_fisheye_import.py)
        _edit_line(cameras, "2 ", lambda line: line.replace(" FULL_OPENCV ", " THIN_PRISM_FISHEYE "))
    elif case == "unknown camera":
        _edit_line(images, "2 ", lambda line: " ".join(line.split()[:8] + ["42"] + line.split()[9:]))
    elif case == "param count":
        _edit_line(cameras, "1 ", lambda line: line.rsplit(" ", 1)[0])
    else:
        target = cameras if "cameras" in case else images
        target.write_bytes(target.read_bytes()[:-7])
    failing = cameras if case in ("fisheye", "param count", "truncated cameras.bin") else images
    with pytest.raises(RigError, match=pattern) as err:
        read_calibrations([images])
    assert str(err.value).startswith(f"{failing}: ") and "\n" not in str(err.value)


def test_detection_and_a_pair_read_once(tmp_path, known_calibration):
    for name in ("cameras.txt", "images.txt", "cameras.bin", "images.bin", "Cameras.TXT", "IMAGES.BIN"):
        assert detect_format(tmp_path / name) == "colmap"
    cameras, images = write_colmap(tmp_path / "model", known_calibration)
    read = read_calibrations([cameras, images])
    assert [c.name for c in read.cameras] == [c.name for c in known_calibration]
    assert read.sources == [str(cameras), str(images)] and read.formats == ["colmap", "colmap"]
    with pytest.raises(RigError, match=r"not found \(a COLMAP model is cameras\.txt \+ images\.txt"):
        images.unlink()
        read_calibrations([cameras])
