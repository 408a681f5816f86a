"""Every malformed calibration gives one line naming the file and the field (or the option)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.app.rig.easymocap import write_easymocap
from silpose.app.rig.examples import one_wall_lab
from silpose.app.rig.image_size import resolve_image_size
from silpose.app.rig.importer import ImportOptions, import_rig
from silpose.app.rig.opencv import read_opencv, write_opencv_camera
from silpose.app.rig.pose2sim import write_pose2sim
from silpose.shared.camera import RigError, default_rig, look_at

GOOD = {
    "camera_matrix": "!!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 500., 0., 321.5, 0., 500., 242.5, 0., 0., 1. ]",
    "distortion_coefficients": "[ -0.1, 0.01, 0., 0., 0. ]",
    "rotation_vectors": "[ 2.0, 0.1, 0.05 ]",
    "translation_vectors": "[ 100., 900., 4000. ]",
}


def yml(tmp_path, name="cam1.yml", drop=(), **fields):
    """A YAML calibration from GOOD with fields dropped or replaced (value strings)."""
    f = {k: v for k, v in {**GOOD, **fields}.items() if k not in drop and v is not None}
    p = tmp_path / name
    p.write_text("%YAML:1.0\n---\n" + "".join(f"{k}: {v}\n" for k, v in f.items()))
    return p


def error_of(paths, **opts) -> str:
    with pytest.raises(RigError) as info:
        import_rig(paths if isinstance(paths, list) else [paths], ImportOptions(**{"unit": "mm", "step": 0.2, **opts}))
    msg = str(info.value)
    assert "\n" not in msg, msg
    return msg


@pytest.mark.parametrize("drop, replace, words", [
    (("rotation_vectors",), {"calibration_Time": '"08/19/11"', "nrOfFrames": "8"},
     ["missing field rotation", "rvec", "rvector", "keys silpose does not read here: calibration_Time, nrOfFrames"]),
    (("camera_matrix",), {}, ["missing field camera matrix"]),
    (("translation_vectors",), {}, ["missing field translation"]),
    ((), {"camera_matrix": "[ 500., 0., 321.5, 0., 500., 242.5 ]"}, ["field camera_matrix", "3x3"]),
    ((), {"rotation_vectors": "!!opencv-matrix\n   rows: 8\n   cols: 3\n   dt: d\n   data: [" + ", ".join(["0.1"] * 24) + "]"},
     ["field rotation_vectors", "8 rotation vectors (one per calibration image?)"]),
    ((), {"rotation_vectors": "[0.0, 0.34, 0.03, 0.93]"}, ["field rotation_vectors", "quaternion"]),
    ((), {"Rotation": "!!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [1., 0., 0., 0., 1., 0., 0., 0., 2.]"},
     ["field Rotation", "not a rotation matrix"]),
    ((), {"R": "!!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [1., 0., 0., 0., 1., 0., 0., 0., 1.]"},
     ["field R", "disagrees with field rotation_vectors"]),
    ((), {"translation_vectors": "[ 100., .nan, 4000. ]"}, ["field translation_vectors", "NaN"]),
    ((), {"distortion_coefficients": "[ 0.1, 0.2, 0.3 ]"}, ["field distortion_coefficients", "4, 5, 8, 12 or 14"]),
    ((), {"camera_matrix": "!!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ -500., 0., 321.5, 0., 500., 242.5, 0., 0., 1. ]"},
     ["field camera_matrix", "fx, fy > 0"]),
    ((), {"image_size": "[ 644, 486 ]", "image_width": "640", "image_height": "480"},
     ["conflicts with field image_size", "640x480"]),
    ((), {"image_width": "644.5", "image_height": "486"}, ["field image_width", "whole number"]),
    ((), {"image_width": "644"}, ["field image_width", "come together"]),
])
def test_malformed_opencv_files(tmp_path, drop, replace, words):
    p = yml(tmp_path, drop=drop, **replace)
    msg = error_of(p, image_size="644x486" if not any("image" in k for k in replace) else None)
    assert msg.startswith(str(p)), msg
    for w in words:
        assert w in msg, (w, msg)


def test_unreadable_and_unknown_files(tmp_path):
    bad = tmp_path / "cam.yml"
    bad.write_text("%YAML:1.0\nK: [1, 2\n")
    assert error_of(bad).startswith(f"{bad}: not a readable OpenCV FileStorage file")
    txt = tmp_path / "cam.txt"
    txt.write_text("K = 1")
    msg = error_of(txt)
    assert msg.startswith(f"{txt}: unknown calibration format") and "--format" in msg
    assert error_of(tmp_path / "absent.xml").startswith(f"{tmp_path / 'absent.xml'}: calibration file not found")


def test_image_size_problems(tmp_path):
    p = yml(tmp_path, image_width="1920", image_height="1080")
    msg = error_of(p, image_size="644x486")
    assert msg.startswith(str(p)) and "conflicting image sizes" in msg and "1920x1080" in msg and "644x486" in msg
    q = yml(tmp_path, name="cam2.yml")
    msg = error_of(q)
    assert msg.startswith(str(q)) and "image size unknown" in msg and "--image-size" in msg
    msg = error_of(q, image_size="320x240")  # the principal point (321.5, 242.5) is outside a 320x240 image
    assert msg.startswith(str(q)) and "principal point" in msg and "--image-size" in msg
    assert error_of(q, image_size="644by486").startswith("--image-size: expected WIDTHxHEIGHT")


def test_image_size_read_from_an_image_next_to_the_file(tmp_path):
    p = yml(tmp_path)
    (tmp_path / "images" / "cam_1").mkdir(parents=True)  # spelling-insensitive: cam_1 is cam1
    cv2.imwrite(str(tmp_path / "images" / "cam_1" / "000000.png"), np.zeros((486, 644), np.uint8))
    size, how = resolve_image_size(read_opencv(p)[0], None)
    assert size == (644, 486) and how.endswith("000000.png")


def lab_files(tmp_path, turn=None):
    calib, _ = one_wall_lab()
    if turn is not None:  # point that camera at the wall behind it
        c = calib[turn]
        centre = -c.R.T @ c.t
        R, _ = look_at(centre, centre + np.array([0.0, 3000.0, 0.0]), up=(0, 0, -1))
        calib[turn] = type(c)(c.name, c.K, c.dist, R, -R @ centre, c.size, c.source)
    paths = []
    for c in calib:
        paths.append(tmp_path / f"{c.name}.xml")
        write_opencv_camera(paths[-1], c)
    return paths


def test_cameras_facing_away_wrong_up_wrong_unit_and_options(tmp_path):
    paths = lab_files(tmp_path, turn=2)
    msg = error_of(paths, image_size="644x486")
    assert msg.startswith(str(paths[0])) and "camera(s) 'cam3' see a 2 m person nowhere" in msg and "--show rig.png" in msg
    (tmp_path / "good").mkdir()
    good = lab_files(tmp_path / "good")
    msg = error_of(good, image_size="644x486", up="+z")
    assert "camera 'cam1' is 2.00 m below the floor" in msg and "--up" in msg and msg.startswith(str(good[0]))
    msg = error_of(good, image_size="644x486", unit="m")
    assert "2000 m above the floor" in msg and "--unit" in msg
    assert error_of(good, image_size="644x486", unit="furlong").startswith("--unit: expected one of mm")
    assert error_of(good, image_size="644x486", up="down").startswith("--up: expected auto or one of")
    assert error_of(good, image_size="644x486", origin="1,2").startswith("--origin: expected auto or X,Y,Z")
    assert error_of(good, image_size="644x486", workspace="big").startswith("--workspace: expected auto, WxH")
    assert error_of(good, image_size="644x486", min_views=5).startswith("--min-views: must be between 1 and 4")
    msg = error_of(good, image_size="644x486", workspace="6x6")
    assert "does not see the workspace corner" in msg and "6.00 m x 6.00 m" in msg


def test_duplicate_names_and_rig_json_with_a_unit(tmp_path, known_calibration):
    a, b = tmp_path / "a.yml", tmp_path / "b.yml"
    write_opencv_camera(a, known_calibration[0])
    write_opencv_camera(b, known_calibration[0])
    msg = error_of([a, b])
    assert msg.startswith(str(b)) and "camera name 'cam0' is also a camera of" in msg and str(a) in msg
    rig = tmp_path / "rig.json"
    rig.write_text(default_rig().to_json())
    assert "a silpose rig is in metres already" in error_of([rig], unit="mm")
    assert "imported on its own" in error_of([rig, a], unit=None)


def test_easymocap_and_pose2sim_problems(tmp_path, known_calibration):
    cams = [type(c)(str(i), c.K, c.dist, c.R, c.t, c.size, c.source) for i, c in enumerate(known_calibration)]
    intri, extri = write_easymocap(tmp_path / "em", cams)
    text = extri.read_text()
    extri.write_text(text.replace('"3"', '"9"', 1))
    msg = error_of([intri])
    assert msg.startswith(str(extri)) and "field names: camera(s) 9 have no intrinsics" in msg
    extri.unlink()
    assert error_of([intri]).startswith(f"{extri}: not found")
    (tmp_path / "em2").mkdir()
    intri2, extri2 = write_easymocap(tmp_path / "em2", cams)
    extri2.write_text(extri2.read_text().replace("T_1:", "Tx_1:"))
    msg = error_of([intri2])
    assert "missing field translation" in msg
    toml = write_pose2sim(tmp_path / "Calib.toml", known_calibration)
    toml.write_text(toml.read_text().replace("fisheye = false", "fisheye = true", 1))
    # a fisheye camera whose distortions are the standard model's five
    assert error_of([toml]).startswith(f"{toml}: field cam_01.distortions: a fisheye camera has 4 coefficients")
    toml.write_text("[metadata]\nadjusted = false\n")
    assert error_of([toml]).startswith(f"{toml}: no camera table")
    toml.write_text("[cam_1\n")
    assert error_of([toml]).startswith(f"{toml}: not a readable TOML file")
    toml.write_text('[cam_1]\nname = "a"\nsize = [644, 486]\nmatrix = [[500, 0, 320], [0, 500, 240], [0, 0, 1]]\n'
                    "distortions = [0, 0, 0, 0]\nrotation = [1, 2]\ntranslation = [0, 0, 5]\n")
    msg = error_of([toml])
    assert msg.startswith(f"{toml}: field cam_1.rotation: expected 3 values")


def test_a_workspace_only_a_folding_lens_model_would_see_is_refused(tmp_path):
    """A real EasyMocap camera (k2 = -1.61): the workspace lies 35-43 deg off its axis, where OpenCV's radial
    model has folded back and projects into the image. The import refuses it, saying why, instead of a rig
    whose camera 'sees' the workspace; without distortion the same pose is refused as outside the image."""
    def write(dist):
        (tmp_path / "intri.yml").write_text(
            '%YAML:1.0\n---\nnames:\n  - "9"\nK_9: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n'
            "  data: [1583.013492, 0.0, 970.378172, 0.0, 1589.725234, 523.944567, 0.0, 0.0, 1.0]\n"
            f"dist_9: !!opencv-matrix\n  rows: 1\n  cols: 5\n  dt: d\n  data: {dist}\n")
        (tmp_path / "extri.yml").write_text(
            '%YAML:1.0\n---\nnames:\n  - "9"\nRot_9: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n'
            "  data: [0.536141, -0.84405, -0.01153, -0.287043, -0.16945, -0.942811, 0.793826, 0.50879, -0.333128]\n"
            "T_9: !!opencv-matrix\n  rows: 3\n  cols: 1\n  dt: d\n  data: [0.217978, 1.19732, 3.469565]\n")
        return [tmp_path / "intri.yml", tmp_path / "extri.yml"]

    opts = dict(unit="m", image_size="1920x1080", origin="-1.9,0.75,0", workspace="0.1x0.1", person_height=0.5)
    msg = error_of(write("[0.005225, -1.613793, -0.005377, -0.000435, 0.0]"), **opts)
    assert "camera '9' does not see the workspace corner" in msg and "beyond where its lens distortion model is valid" in msg
    msg = error_of(write("[0.0, 0.0, 0.0, 0.0, 0.0]"), **opts)
    assert "camera '9' does not see the workspace corner" in msg and "projects to" in msg
