"""Every calibration format round-trips: a known rig with distortion, written in a millimetre, z-down
frame whose origin is a floor corner, imports back with the same camera names and the same projections
(<= 1e-9 px against cv2.projectPoints on the original calibration, through the stored transform)."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.app.rig.easymocap import write_easymocap
from silpose.app.rig.formats import detect_format
from silpose.app.rig.importer import ImportOptions, import_rig, write_rig
from silpose.app.rig.opencv import read_opencv, write_opencv_camera
from silpose.app.rig.pose2sim import write_pose2sim
from silpose.shared.camera import RigError, load_rig

SPELLING_NAMES = ["opencv_sample", "calibrate_camera", "capitalised", "short", "intrinsics", "course_vecs",
                  "course_values"]


def options(**kw):
    return ImportOptions(unit="mm", step=0.2, **kw)


@pytest.mark.parametrize("suffix", [".xml", ".yml", ".yaml"])
@pytest.mark.parametrize("spelling", SPELLING_NAMES)
def test_opencv_per_camera_files_in_every_spelling(tmp_path, suffix, spelling, known_calibration, spelled_writer,
                                                   check_same_projections):
    paths = []
    for c in known_calibration:
        p = tmp_path / f"{c.name}{suffix}"
        spelled_writer(p, c, spelling)
        paths.append(p)
    assert {detect_format(p) for p in paths} == {"opencv"}
    result = import_rig(paths, options())
    check_same_projections(result.rig, known_calibration)
    up = result.rig.transform.up_in_calibration
    assert up.tolist() == [0.0, 0.0, -1.0]  # found the z-down world


def test_opencv_files_mixing_spellings_cases_and_formats_keep_the_file_stems_as_names(
        tmp_path, known_calibration, spelled_writer, check_same_projections):
    """cam1.xml is called cam1 (never renumbered), whatever the order and spelling of the files."""
    renamed = [type(c)(f"cam{i + 1}", c.K, c.dist, c.R, c.t, c.size, c.source) for i, c in enumerate(known_calibration)]
    paths = []
    for c, spelling, suffix in zip(renamed, SPELLING_NAMES, [".xml", ".yml", ".yaml", ".xml"]):
        p = tmp_path / f"{c.name}{suffix}"
        spelled_writer(p, c, spelling)
        paths.append(p)
    result = import_rig(paths[::-1], options())
    check_same_projections(result.rig, renamed[::-1])
    assert result.rig.names == ("cam4", "cam3", "cam2", "cam1")


def test_one_opencv_file_for_all_cameras_named_by_its_sections(tmp_path, known_calibration, check_same_projections):
    import cv2

    p = tmp_path / "rig_calibration.yml"
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
    for c in known_calibration:
        fs.startWriteStruct(f"{c.name}_front", cv2.FileNode_MAP)
        fs.write("Camera_Matrix", c.K)
        fs.write("Distortion_Coefficients", c.dist.reshape(-1, 1))
        fs.write("Rotation_Matrix", c.R)
        fs.write("Translation_Vector", c.t.reshape(3, 1))
        fs.write("Image_Size", np.array([c.size], np.float64))
        fs.endWriteStruct()
    fs.release()
    result = import_rig([p], options())
    renamed = [type(c)(f"{c.name}_front", c.K, c.dist, c.R, c.t, c.size, c.source) for c in known_calibration]
    check_same_projections(result.rig, renamed)


def test_opencv_writer_round_trip_with_the_name_field(tmp_path, known_calibration):
    c = known_calibration[2]
    for rotation in ("rvec", "matrix", "both"):
        p = tmp_path / f"x_{rotation}.xml"
        write_opencv_camera(p, c, rotation=rotation)
        (back,) = read_opencv(p)
        assert back.name == c.name and back.size == c.size
        np.testing.assert_allclose(back.R, c.R, atol=1e-15)
        np.testing.assert_array_equal(back.t, c.t)


def test_easymocap_pair(tmp_path, known_calibration, check_same_projections):
    renamed = [type(c)(str(i + 1), c.K, c.dist, c.R, c.t, c.size, c.source) for i, c in enumerate(known_calibration)]
    intri, extri = write_easymocap(tmp_path, renamed)
    assert detect_format(intri) == detect_format(extri) == "easymocap"
    for given in ([intri], [extri], [intri, extri]):  # either file finds its partner; the pair is read once
        result = import_rig(given, options())
        check_same_projections(result.rig, renamed)


def test_pose2sim_toml(tmp_path, known_calibration, check_same_projections):
    path = write_pose2sim(tmp_path / "Calib.toml", known_calibration)
    assert detect_format(path) == "pose2sim"
    result = import_rig([path], options())
    check_same_projections(result.rig, known_calibration)
    assert "[cam_01]" in path.read_text() and "[metadata]" in path.read_text()


def test_silpose_rig_json_reimports_and_composes_the_transforms(tmp_path, known_calibration, check_same_projections):
    """A rig file imported again (e.g. with another workspace) keeps mapping the lab's points right."""
    first = import_rig(_pose2sim(tmp_path, known_calibration), options())
    path = write_rig(first.rig, tmp_path / "rig.json")
    assert detect_format(path) == "silpose"
    again = import_rig([path], ImportOptions(workspace="2x2@0.5,0", origin="0.5,0,0", step=0.2))
    check_same_projections(again.rig, known_calibration)
    assert again.rig.workspace.describe() == "2.00 m x 2.00 m centred at (0.50, 0.00) m"
    back = load_rig(path)
    check_same_projections(back, known_calibration)
    assert back.source == str(path) and first.rig.source.endswith("Calib.toml")


def _pose2sim(tmp_path, calibration):
    return [write_pose2sim(tmp_path / "Calib.toml", calibration)]


def test_easymocap_cameras_without_extrinsics_are_left_out_and_said(tmp_path, known_calibration):
    cams = [type(c)(str(i + 1), c.K, c.dist, c.R, c.t, c.size, c.source) for i, c in enumerate(known_calibration)]
    intri, extri = write_easymocap(tmp_path, cams)
    write_easymocap(tmp_path / "fewer", cams[:3])
    extri.write_text((tmp_path / "fewer" / "extri.yml").read_text())  # camera 4 has intrinsics only
    result = import_rig([intri], options())
    assert result.rig.names == ("1", "2", "3")
    assert any("camera(s) 4 have intrinsics but no extrinsics" in n for n in result.notes)


def test_per_camera_folders_of_same_named_files_are_named_by_their_folders(tmp_path, known_calibration,
                                                                           spelled_writer, check_same_projections):
    """cam1/config.xml ... cam4/config.xml (no name field): the cameras are cam1 ... cam4, said in a note; with a
    name field the file's name wins; one folder name used twice is still a clash (one line)."""
    paths = []
    for c in known_calibration:
        (tmp_path / c.name).mkdir()
        paths.append(tmp_path / c.name / "config.xml")
        spelled_writer(paths[-1], c, "course_vecs", size=True)
    result = import_rig(paths, options())
    check_same_projections(result.rig, known_calibration)
    assert sum("after its folder" in n for n in result.notes) == len(paths)
    twin = tmp_path / "config.xml"  # one more config.xml, in the folder above: two cameras would be 'tmp...'
    twin.write_bytes(paths[0].read_bytes())
    named = import_rig([paths[0], twin], options())  # different folders: cam names from the folders
    assert named.rig.names == (paths[0].parent.name, tmp_path.name)
    dup = tmp_path / "other" / known_calibration[0].name
    dup.mkdir(parents=True)
    (dup / "config.xml").write_bytes(paths[0].read_bytes())
    with pytest.raises(RigError, match=r"camera name '[^']+' is also a camera of"):
        import_rig([paths[0], dup / "config.xml"], options())  # two folders of one name: a clash, one line


def _windows_text(path) -> None:
    """``path`` rewritten as a Windows editor saves text: a UTF-8 byte-order mark and CRLF line ends."""
    text = path.read_bytes().decode("utf-8").replace("\r\n", "\n").replace("\n", "\r\n")
    path.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))


@pytest.mark.parametrize("kind", ["pose2sim", "easymocap", "opencv"])
def test_calibrations_saved_by_windows_editors_import_the_same(tmp_path, known_calibration, check_same_projections,
                                                               kind):
    if kind == "pose2sim":
        paths = [write_pose2sim(tmp_path / "Calib.toml", known_calibration)]
    elif kind == "easymocap":
        paths = list(write_easymocap(tmp_path, known_calibration))
    else:
        paths = []
        for c in known_calibration:
            paths.append(tmp_path / f"{c.name}.yml")
            write_opencv_camera(paths[-1], c)
    for p in paths:
        _windows_text(p)
    res = import_rig(paths, options())
    check_same_projections(res.rig, known_calibration)
