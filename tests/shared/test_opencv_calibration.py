"""Tests of silpose.shared.opencv_calibration: OpenCV FileStorage rigs in, projections unchanged."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.shared.camera import Camera, Rig, RigError, default_rig, load_rig
from silpose.shared.opencv_calibration import read_opencv_cameras, rotation_to_rvec, write_opencv_camera

DIST = np.array([-0.21, 0.08, 0.0013, -0.0009, -0.012])


def distorted_rig() -> Rig:
    """The default rig with non-zero distortion on every camera (a different one each)."""
    return Rig(
        tuple(
            Camera(c.name, c.K, c.R, c.t, c.width, c.height, dist=DIST * (1 + 0.1 * i))
            for i, c in enumerate(default_rig())
        )
    )


def workspace_points(n=200, seed=0):
    return np.random.default_rng(seed).uniform([-1.5, -1.5, 0.0], [1.5, 1.5, 2.0], size=(n, 3))


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


def good_fields(cam: Camera) -> dict:
    return {
        "camera_matrix": cam.K,
        "distortion_coefficients": cam.dist.reshape(1, -1),
        "rvec": cv2.Rodrigues(cam.R)[0],
        "tvec": cam.t.reshape(3, 1),
        "image_width": cam.width,
        "image_height": cam.height,
    }


@pytest.mark.parametrize("suffix", [".xml", ".yml", ".yaml"])
@pytest.mark.parametrize("rotation", ["rvec", "matrix"])
@pytest.mark.parametrize("unit", [1.0, 0.001])
def test_written_rig_loads_back_with_identical_projections(tmp_path, suffix, rotation, unit):
    rig = distorted_rig()
    paths = []
    for cam in rig:
        p = tmp_path / f"{cam.name}{suffix}"
        write_opencv_camera(p, cam, unit=unit, rotation=rotation)
        paths.append(p)
    assert not list(tmp_path.glob(".*tmp*"))  # the temporary files were renamed
    back = load_rig(paths, unit=unit)
    assert back.names == rig.names
    X = workspace_points()
    for a, b in zip(rig, back):
        np.testing.assert_allclose(b.project(X), a.project(X), rtol=1e-9, atol=0)
        rvec, _ = cv2.Rodrigues(a.R)
        ref, _ = cv2.projectPoints(X, rvec, a.t, a.K, a.dist)
        np.testing.assert_allclose(b.project(X), ref.reshape(-1, 2), rtol=1e-9, atol=0)
        np.testing.assert_allclose(b.t, a.t, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(b.dist, a.dist)
        assert (b.width, b.height) == (a.width, a.height)


def test_millimetre_file_really_holds_millimetres(tmp_path):
    cam = default_rig()[1]
    write_opencv_camera(tmp_path / "c.yml", cam, unit=0.001)
    fs = cv2.FileStorage(str(tmp_path / "c.yml"), cv2.FILE_STORAGE_READ)
    np.testing.assert_allclose(fs.getNode("tvec").mat().ravel(), cam.t * 1000, rtol=1e-12)
    fs.release()
    # Read with the wrong unit, the translation is 1000x too large.
    wrong = read_opencv_cameras(tmp_path / "c.yml", unit=1.0)[0]
    np.testing.assert_allclose(wrong.t, cam.t * 1000, rtol=1e-12)


def test_alternative_keys_plain_sequences_and_missing_distortion(tmp_path):
    cam = default_rig()[2]
    p = tmp_path / "alt.xml"
    write_fields(
        p,
        {
            "camera_name": "left",
            "cameraMatrix": cam.K,
            "R": cam.R,
            "T": list(cam.t * 1000.0),
            "imageSize": [cam.width, cam.height],
        },
    )
    (back,) = read_opencv_cameras(p, unit=0.001)
    assert back.name == "left"
    np.testing.assert_array_equal(back.dist, np.zeros(5))
    X = workspace_points(50)
    np.testing.assert_allclose(back.project(X), cam.project(X), rtol=1e-9)
    # Four distortion coefficients (k1 k2 p1 p2) under the short key "D".
    p4 = tmp_path / "d4.yml"
    write_fields(p4, _drop(good_fields(cam), "distortion_coefficients") | {"D": DIST[:4]})
    (b4,) = read_opencv_cameras(p4)
    np.testing.assert_array_equal(b4.dist, DIST[:4])
    rvec, _ = cv2.Rodrigues(cam.R)
    ref, _ = cv2.projectPoints(X, rvec, cam.t, cam.K, DIST[:4])
    np.testing.assert_allclose(b4.project(X), ref.reshape(-1, 2), rtol=1e-9)


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
    X = workspace_points(50)
    (a,) = read_opencv_cameras(yml, unit=0.001)
    (b,) = read_opencv_cameras(xml, unit=0.001, default_name="xmlcam")
    assert (a.name, b.name) == ("side", "xmlcam")
    ref, _ = cv2.projectPoints(X, rvec, cam.t, K, DIST)
    np.testing.assert_allclose(a.project(X), ref.reshape(-1, 2), rtol=1e-9)
    np.testing.assert_allclose(b.project(X), cam.project(X), rtol=1e-9)
    # A ragged nested list is a malformed field.
    yml.write_text(yml.read_text().replace(f"[{fmt(K[2])}]", "[0, 1]"))
    with pytest.raises(RigError, match=r"field K\b"):
        read_opencv_cameras(yml)


def test_default_name_and_several_cameras_in_one_file(tmp_path):
    rig = distorted_rig()
    p = tmp_path / "one.yml"
    fields = good_fields(rig[0])
    write_fields(p, fields)
    assert read_opencv_cameras(p, default_name="front")[0].name == "front"
    multi = tmp_path / "rig.yaml"
    write_fields(multi, {f"view{i}": good_fields(c) for i, c in enumerate(rig)} | {"comment": "4 views"})
    cams = load_rig(multi)
    assert cams.names == ("view0", "view1", "view2", "view3")
    X = workspace_points(50)
    np.testing.assert_allclose(cams.project(X), rig.project(X), rtol=1e-9)


def test_consistent_rvec_and_matrix_are_accepted_inconsistent_rejected(tmp_path):
    cam = default_rig()[0]
    p = tmp_path / "both.yml"
    write_fields(p, good_fields(cam) | {"rotation_matrix": cam.R})
    np.testing.assert_allclose(read_opencv_cameras(p)[0].R, cam.R, atol=1e-12)
    write_fields(p, good_fields(cam) | {"rotation_matrix": default_rig()[1].R})
    with pytest.raises(RigError, match="rvec.*disagrees"):
        read_opencv_cameras(p)


def _drop(d, *keys):
    return {k: v for k, v in d.items() if k not in keys}


CAM = default_rig()[0]
GOOD = good_fields(CAM)
MALFORMED = {
    "no_matrix": (_drop(GOOD, "camera_matrix"), "camera matrix"),
    "matrix_shape": (GOOD | {"camera_matrix": np.eye(3)[:2]}, "camera_matrix"),
    "matrix_nan": (GOOD | {"camera_matrix": np.diag([np.nan, 1.0, 1.0])}, "camera_matrix"),
    "negative_focal": (GOOD | {"camera_matrix": CAM.K * [[-1], [1], [1]]}, "field K"),
    "no_rotation": (_drop(GOOD, "rvec"), "rotation"),
    "rvec_shape": (GOOD | {"rvec": np.zeros(4)}, "rvec"),
    "not_rotation": (_drop(GOOD, "rvec") | {"rotation_matrix": 2 * CAM.R}, "rotation_matrix"),
    "reflection": (_drop(GOOD, "rvec") | {"R": -CAM.R}, "R"),
    "no_translation": (_drop(GOOD, "tvec"), "translation"),
    "translation_text": (GOOD | {"tvec": "far away"}, "tvec"),
    "no_size": (_drop(GOOD, "image_width", "image_height"), "image size"),
    "height_missing": (_drop(GOOD, "image_height"), "image_height"),
    "width_fraction": (GOOD | {"image_width": 320.5}, "image_width"),
    "size_shape": (_drop(GOOD, "image_width", "image_height") | {"image_size": [320]}, "image_size"),
    "dist_count": (GOOD | {"distortion_coefficients": np.zeros(3)}, "distortion_coefficients"),
    "name_number": (GOOD | {"name": 7}, "name"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_fields_raise_rig_error_naming_file_and_field(tmp_path, case):
    fields, field = MALFORMED[case]
    p = tmp_path / f"{case}.yml"
    write_fields(p, fields)
    with pytest.raises(RigError) as info:
        load_rig([p])
    msg = str(info.value)
    assert str(p) in msg and field in msg and "\n" not in msg


@pytest.mark.parametrize(
    "name, text, what",
    [
        ("garbage.xml", "this is not xml", "not a readable"),
        ("empty.yml", "", "not a readable"),
        ("broken.yml", "%YAML:1.0\n---\ncamera_matrix: [1, 2\n", "not a readable"),
        (
            "badmatrix.yml",
            "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  data: [1, 2]\n",
            "camera_matrix",
        ),
        ("nocamera.yml", "%YAML:1.0\n---\nfoo: 1\nbar: {a: 2}\n", "camera matrix"),
    ],
)
def test_unreadable_files_raise_rig_error(tmp_path, name, text, what):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(RigError, match=what) as info:
        read_opencv_cameras(p)
    assert str(p) in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(RigError, match="not found"):
        read_opencv_cameras(tmp_path / "missing.yml")
    with pytest.raises(RigError, match="unit"):
        read_opencv_cameras(p, unit=0.0)


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
    with pytest.raises(RigError, match=r"\.json"):
        write_opencv_camera(tmp_path / "c.json", CAM)
    with pytest.raises(ValueError, match="rotation"):
        write_opencv_camera(tmp_path / "c.yml", CAM, rotation="quaternion")
