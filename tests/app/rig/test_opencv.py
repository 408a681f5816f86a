"""silpose.app.rig.opencv: OpenCV FileStorage calibrations in, the same camera out (any spelling)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.app.rig.calibration import CalibratedCamera, rotation_to_rvec
from silpose.app.rig.opencv import read_opencv, write_opencv_camera
from silpose.shared.camera import RigError, default_rig

DIST = np.array([-0.21, 0.08, 0.0013, -0.0009, -0.012])


def calibrated(cam, dist=DIST, size=True) -> CalibratedCamera:
    return CalibratedCamera(cam.name, cam.K, dist, cam.R, cam.t * 1000.0, (cam.width, cam.height) if size else None, "x")


def write_fields(path, fields: dict) -> None:
    """Write ``fields`` (name -> str | int | array | list of numbers | dict of fields) with cv2.FileStorage."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)

    def put(key, value):
        if isinstance(value, dict):
            fs.startWriteStruct(key, cv2.FileNode_MAP)
            for k, v in value.items():
                put(k, v)
            fs.endWriteStruct()
        elif isinstance(value, list):
            fs.startWriteStruct(key, cv2.FileNode_SEQ)
            for v in value:
                fs.write("", v)
            fs.endWriteStruct()
        elif isinstance(value, np.ndarray):
            fs.write(key, value.astype(np.float64))
        else:
            fs.write(key, value)

    for k, v in fields.items():
        put(k, v)
    fs.release()


def good_fields(cam) -> dict:
    return {"camera_matrix": cam.K, "distortion_coefficients": DIST.reshape(1, -1), "rvec": cv2.Rodrigues(cam.R)[0],
            "tvec": cam.t.reshape(3, 1), "image_width": cam.width, "image_height": cam.height}


def same(a: CalibratedCamera, b: CalibratedCamera, atol_R=1e-15):
    np.testing.assert_array_equal(a.K, b.K)
    np.testing.assert_allclose(a.R, b.R, atol=atol_R, rtol=0)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.dist, b.dist)
    assert a.size == b.size


@pytest.mark.parametrize("suffix", [".xml", ".yml", ".yaml"])
@pytest.mark.parametrize("rotation", ["rvec", "matrix", "both"])
def test_written_cameras_read_back_exactly(tmp_path, suffix, rotation):
    for c in default_rig():  # cam2 faces -x: a rotation angle of exactly pi
        cam = calibrated(c)
        p = tmp_path / f"{cam.name}{suffix}"
        write_opencv_camera(p, cam, rotation=rotation)
        (back,) = read_opencv(p)
        assert back.name == cam.name and back.source == str(p)
        same(back, cam)
    assert not list(tmp_path.glob(".*tmp*"))  # the temporary files were renamed


def test_alternative_keys_plain_sequences_and_missing_distortion(tmp_path):
    cam = default_rig()[2]
    p = tmp_path / "alt.xml"
    write_fields(p, {"camera_name": "left", "cameraMatrix": cam.K, "R": cam.R, "T": list(cam.t * 1000.0),
                     "imageSize": [cam.width, cam.height]})
    (back,) = read_opencv(p)
    assert back.name == "left" and back.size == (cam.width, cam.height)
    np.testing.assert_array_equal(back.dist, np.zeros(5))
    np.testing.assert_array_equal(back.R, cam.R)
    p4 = tmp_path / "d4.yml"  # four coefficients (k1 k2 p1 p2) under the short key "D"
    write_fields(p4, {k: v for k, v in good_fields(cam).items() if k != "distortion_coefficients"} | {"D": DIST[:4]})
    np.testing.assert_array_equal(read_opencv(p4)[0].dist, DIST[:4])


def test_hand_written_yaml_and_xml_with_nested_lists(tmp_path):
    """Files typed by a user: nested-list matrices, plain sequences, no opencv-matrix tags."""
    cam = default_rig()[3]
    K, t, R = cam.K, cam.t * 1000.0, cam.R
    rvec = rotation_to_rvec(R)
    fmt = lambda v: ", ".join(repr(float(x)) for x in np.ravel(v))  # noqa: E731
    yml = tmp_path / "hand.yml"
    yml.write_text(
        "%YAML:1.0\n---\n"
        f"name: side\nK: [[{fmt(K[0])}], [{fmt(K[1])}], [{fmt(K[2])}]]\n"
        f"dist: [{fmt(DIST)}]\nrotation_vector: [{fmt(rvec)}]\ntranslation: [{fmt(t)}]\n"
        f"image_size: [{cam.width}, {cam.height}]\n"
    )
    xml = tmp_path / "hand.xml"
    xml.write_text(
        '<?xml version="1.0"?>\n<opencv_storage>\n'
        f"<M>{fmt(K).replace(',', '')}</M>\n<rotation>{fmt(R).replace(',', '')}</rotation>\n"
        f"<t>{fmt(t).replace(',', '')}</t>\n<image_width>{cam.width}</image_width>\n"
        f"<image_height>{cam.height}</image_height>\n</opencv_storage>\n"
    )
    (a,) = read_opencv(yml)
    (b,) = read_opencv(xml)
    assert (a.name, b.name) == ("side", "hand")  # no name field: the file's stem
    np.testing.assert_allclose(a.R, R, atol=1e-15)
    np.testing.assert_array_equal(b.R, R)
    np.testing.assert_array_equal(a.t, t)
    yml.write_text(yml.read_text().replace(f"[{fmt(K[2])}]", "[0, 1]"))  # a ragged nested list
    with pytest.raises(RigError, match=r"field K\b"):
        read_opencv(yml)


def test_several_cameras_in_one_file_named_by_their_sections(tmp_path):
    multi = tmp_path / "rig.yaml"
    write_fields(multi, {f"view{i}": good_fields(c) for i, c in enumerate(default_rig())} | {"comment": "4 views"})
    cams = read_opencv(multi)
    assert [c.name for c in cams] == ["view0", "view1", "view2", "view3"]
    assert [c.where for c in cams] == ["view0.", "view1.", "view2.", "view3."]
    write_fields(multi, {"a": good_fields(default_rig()[0]) | {"translation_vector": np.zeros(2)}})
    with pytest.raises(RigError, match=r"field a\.translation_vector: expected 3 values"):
        read_opencv(multi)


def test_consistent_spellings_are_accepted_inconsistent_rejected(tmp_path):
    cam = default_rig()[0]
    p = tmp_path / "both.yml"
    write_fields(p, good_fields(cam) | {"rotation_matrix": cam.R, "TVector": cam.t})
    np.testing.assert_allclose(read_opencv(p)[0].R, cam.R, atol=1e-12)
    write_fields(p, good_fields(cam) | {"rotation_matrix": default_rig()[1].R})
    with pytest.raises(RigError, match="rotation_matrix: disagrees with field rvec"):
        read_opencv(p)
    write_fields(p, good_fields(cam) | {"T": cam.t + 1})
    with pytest.raises(RigError, match="T: disagrees with field tvec"):
        read_opencv(p)


def _drop(d, *keys):
    return {k: v for k, v in d.items() if k not in keys}


CAM = default_rig()[0]
GOOD = good_fields(CAM)
MALFORMED = {
    "no_matrix": (_drop(GOOD, "camera_matrix"), "camera matrix"),
    "matrix_shape": (GOOD | {"camera_matrix": np.eye(3)[:2]}, "camera_matrix"),
    "matrix_nan": (GOOD | {"camera_matrix": np.diag([np.nan, 1.0, 1.0])}, "camera_matrix"),
    "negative_focal": (GOOD | {"camera_matrix": CAM.K * [[-1], [1], [1]]}, "camera_matrix"),
    "no_rotation": (_drop(GOOD, "rvec"), "rotation"),
    "rvec_shape": (GOOD | {"rvec": np.zeros(4)}, "rvec"),
    "not_rotation": (_drop(GOOD, "rvec") | {"rotation_matrix": 2 * CAM.R}, "rotation_matrix"),
    "reflection": (_drop(GOOD, "rvec") | {"R": -CAM.R}, "R"),
    "no_translation": (_drop(GOOD, "tvec"), "translation"),
    "translation_text": (GOOD | {"tvec": "far away"}, "tvec"),
    "height_missing": (_drop(GOOD, "image_height"), "image_width"),
    "width_fraction": (GOOD | {"image_width": 320.5}, "image_width"),
    "size_shape": (_drop(GOOD, "image_width", "image_height") | {"image_size": [320]}, "image_size"),
    "dist_count": (GOOD | {"distortion_coefficients": np.zeros(3)}, "distortion_coefficients"),
    "name_list": (GOOD | {"name": [1, 2]}, "name"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_fields_raise_rig_error_naming_file_and_field(tmp_path, case):
    fields, field = MALFORMED[case]
    p = tmp_path / f"{case}.yml"
    write_fields(p, fields)
    with pytest.raises(RigError) as info:
        read_opencv(p)
    msg = str(info.value)
    assert msg.startswith(f"{p}: ") and field in msg and "\n" not in msg, msg


@pytest.mark.parametrize(
    "name, text, what",
    [
        ("garbage.xml", "this is not xml", "not a readable"),
        ("empty.yml", "", "not a readable"),
        ("broken.yml", "%YAML:1.0\n---\ncamera_matrix: [1, 2\n", "not a readable"),
        ("badmatrix.yml", "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [1, 2]\n",
         "camera_matrix"),
        ("nocamera.yml", "%YAML:1.0\n---\nfoo: 1\nbar: {a: 2}\n", "missing field camera matrix"),
    ],
)
def test_unreadable_files_raise_rig_error(tmp_path, name, text, what):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(RigError, match=what) as info:
        read_opencv(p)
    assert str(p) in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(RigError, match="not found"):
        read_opencv(tmp_path / "missing.yml")


def test_rotation_to_rvec_is_accurate_at_every_angle_including_pi():
    rng = np.random.default_rng(5)
    rotations = [c.R for c in default_rig()] + [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
    for i in range(400):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = [rng.uniform(0, np.pi), np.pi - 10 ** rng.uniform(-12, -1), 10 ** rng.uniform(-12, -1), np.pi][i % 4]
        rotations.append(cv2.Rodrigues(axis * angle)[0])
    for R in rotations:
        rvec = rotation_to_rvec(R)
        assert np.linalg.norm(rvec) <= np.pi + 1e-12
        np.testing.assert_allclose(cv2.Rodrigues(rvec)[0], R, atol=5e-15)


def test_write_rejects_bad_arguments(tmp_path):
    cam = calibrated(CAM)
    with pytest.raises(RigError, match=r"\.json"):
        write_opencv_camera(tmp_path / "c.json", cam)
    with pytest.raises(ValueError, match="rotation"):
        write_opencv_camera(tmp_path / "c.yml", cam, rotation="quaternion")


def test_plain_yaml_and_integers_in_double_matrices_are_read(tmp_path):
    """Two quirks of real files: YAML without OpenCV's '%YAML:1.0' header (ROS camera_info style, hand-written),
    and integers in a 'dt: d' matrix, which cv2.FileNode.mat() of OpenCV 4.11 misreads (4.29e9 for 0). Both are
    read as the numbers written; the reference is the text itself."""
    import cv2

    body = ("camera_matrix:\n  rows: 3\n  cols: 3\n  data: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n"
            "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ 0, 0, 0, 0, 0 ]\n"
            "rvec: [0.1, 0.2, 0.3]\ntvec: [0, 0, 3]\nimage_width: 640\nimage_height: 480\n")
    plain = tmp_path / "ros.yaml"
    plain.write_text(body)
    headed = tmp_path / "headed.yml"
    headed.write_text("%YAML:1.0\n---\n" + body)
    fs = cv2.FileStorage(str(headed), cv2.FILE_STORAGE_READ)
    assert np.abs(fs.getNode("distortion_coefficients").mat()).max() > 1e6  # the OpenCV quirk this guards against
    fs.release()
    for p in (plain, headed):
        (cam,) = read_opencv(p)
        np.testing.assert_array_equal(cam.K, [[500, 0, 320], [0, 500, 240], [0, 0, 1]])
        np.testing.assert_array_equal(cam.dist, np.zeros(5))
        np.testing.assert_array_equal(cam.t, [0, 0, 3])
        assert cam.size == (640, 480)


@pytest.mark.parametrize("spelling", [("K1", "D1", "K2", "D2"), ("cameraMatrix1", "distCoeffs1", "cameraMatrix2", "distCoeffs2")])
def test_a_stereo_calibrate_file_is_two_cameras_in_the_first_ones_frame(tmp_path, spelling):
    """cv2.stereoCalibrate's outputs (with stereoRectify's R1, P1 ... beside them, which are not poses): cam1 at
    the identity, cam2 at [R | T]; the values are the ones written."""
    import cv2

    K1 = np.array([[484.3, 0, 241.9], [0, 486.2, 305.0], [0, 0, 1]])
    K2 = np.array([[253.8, 0, 240.6], [0, 254.9, 316.2], [0, 0, 1]])
    D1, D2 = np.array([[0.227, -1.189, -0.004, -0.0019, 1.793]]), np.array([[0.0287, -0.0536, -0.0009, -0.0011, 0.0182]])
    R = cv2.Rodrigues(np.array([0.01, -0.2, 0.02]))[0]
    T = np.array([[-0.12], [0.003], [0.01]])
    path = tmp_path / "stereo.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in zip(spelling, (K1, D1, K2, D2)):
        fs.write(key, value)
    for key, value in (("R", R), ("T", T), ("R1", np.eye(3)), ("P1", np.hstack([K1, np.zeros((3, 1))])),
                       ("frame_width", 480), ("frame_height", 640)):
        fs.write(key, value)
    fs.release()
    cam1, cam2 = read_opencv(path)
    assert (cam1.name, cam2.name) == ("cam1", "cam2") and cam1.size == cam2.size == (480, 640)
    np.testing.assert_array_equal(cam1.K, K1)
    np.testing.assert_array_equal(cam2.K, K2)
    np.testing.assert_array_equal(cam1.dist, D1.ravel())
    np.testing.assert_array_equal(cam2.dist, D2.ravel())
    np.testing.assert_array_equal(cam1.R, np.eye(3))
    np.testing.assert_array_equal(cam1.t, np.zeros(3))
    np.testing.assert_allclose(cam2.R, R, atol=1e-12)
    np.testing.assert_array_equal(cam2.t, T.ravel())
