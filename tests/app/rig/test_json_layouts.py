"""JSON calibrations of other tools (anipose/AIST++, CMU Panoptic, Human3.6M-style as VoxelPose's Shelf
and Campus, XRPrimer): the known rig written in each layout imports back with the same names and the same
projections as cv2.projectPoints on the original calibration (<= 1e-9 px, ``check_same_projections``)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from silpose.app.rig.calibration import rotation_to_rvec
from silpose.app.rig.formats import detect_format, read_calibrations
from silpose.app.rig.importer import ImportOptions, import_rig
from silpose.shared.camera import RigError, load_rig
from silpose.shared.cli import build_app


def options(**kw):
    return ImportOptions(unit="mm", step=0.2, **kw)


def _size(cam):
    return f"{cam.size[0]}x{cam.size[1]}"


def _column(v):
    return [[float(x)] for x in np.ravel(v)]


def _write(path, data):
    path.write_text(json.dumps(data, indent=1))
    return path


def aist_layout(calibration):
    """AIST++ ``cameras/setting1.json`` / aniposelib: a list of anipose camera dicts (Rodrigues rotations)."""
    return [{"name": c.name, "size": list(c.size), "matrix": np.asarray(c.K).tolist(),
             "distortions": np.asarray(c.dist).tolist(), "rotation": rotation_to_rvec(c.R).tolist(),
             "translation": np.asarray(c.t).tolist()} for c in calibration]


def panoptic_layout(calibration, extra_vga: int = 0):
    """CMU Panoptic ``calibration_<seq>.json``: HD cameras 00_XX, plus VGA cameras 01_XX (copies here)."""
    cams = []
    for panel, kind, count in ((0, "hd", len(calibration)), (1, "vga", extra_vga)):
        for i, c in enumerate(calibration[:count]):
            cams.append({"name": f"{panel:02d}_{i:02d}", "type": kind, "resolution": list(c.size), "panel": panel,
                         "node": i, "K": np.asarray(c.K).tolist(), "distCoef": np.asarray(c.dist).tolist(),
                         "R": np.asarray(c.R).tolist(), "t": _column(c.t)})
    return {"calibDataSource": "160224_calib_norm", "cameras": cams}


def human36m_layout(calibration, split="fxfy"):
    """VoxelPose's calibration_shelf.json (fx, fy, cx, cy) or 3d-pose-baseline's (f, c): T is the camera centre."""
    out = {}
    for i, c in enumerate(calibration):
        K, d = np.asarray(c.K), np.asarray(c.dist)
        rec = {"R": np.asarray(c.R).tolist(), "T": _column(-np.asarray(c.R).T @ c.t),
               "k": _column([d[0], d[1], d[4]]), "p": _column(d[2:4])}
        if split == "fxfy":
            rec.update(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2], cy=K[1, 2])
        else:
            rec.update(f=_column([K[0, 0], K[1, 1]]), c=_column(K[:2, 2]), name=c.name)
        out[str(i) if split == "fxfy" else c.name] = rec
    return out


def test_aist_list_of_anipose_cameras(tmp_path, known_calibration, check_same_projections):
    path = _write(tmp_path / "setting1.json", aist_layout(known_calibration))
    assert detect_format(path) == "json"
    result = import_rig([path], options())
    check_same_projections(result.rig, known_calibration)
    assert "as json" in result.notes[0]


def test_panoptic_cameras_list_with_hd_selected(tmp_path, known_calibration, check_same_projections):
    path = _write(tmp_path / "calibration_160224_haggling1.json", panoptic_layout(known_calibration, extra_vga=3))
    everything = read_calibrations([path])
    assert [c.name for c in everything.cameras][-3:] == ["01_00", "01_01", "01_02"]
    result = import_rig([path], options(cameras="00_*"))
    renamed = [type(c)(f"00_{i:02d}", c.K, c.dist, c.R, c.t, c.size, c.source) for i, c in enumerate(known_calibration)]
    check_same_projections(result.rig, renamed)
    assert any("kept 4 camera(s) matching --cameras 00_*" in n for n in result.notes)
    assert not any("cameras: each is a view" in n for n in result.notes)
    dome = panoptic_layout(known_calibration * 5, extra_vga=0)  # 20 HD cameras (copies): a warning, not an error
    many = import_rig([_write(tmp_path / "dome.json", dome)], options())
    assert any(n.startswith("warning: 20 cameras: each is a view") and "--cameras" in n for n in many.notes)
    with pytest.raises(RigError, match=r"--cameras: '02_\*' matches none of the cameras \(00_00, 00_01"):
        read_calibrations([path], cameras="00_00,02_*")


@pytest.mark.parametrize("split", ["fxfy", "fc"])
def test_human36m_style_reads_T_as_the_camera_centre(tmp_path, split, known_calibration, check_same_projections):
    path = _write(tmp_path / "calibration_shelf.json", human36m_layout(known_calibration, split))
    size = _size(known_calibration[0])
    result = import_rig([path], options(image_size=size))
    names = [str(i) for i in range(len(known_calibration))] if split == "fxfy" else None
    expected = known_calibration if names is None else [
        type(c)(n, c.K, c.dist, c.R, c.t, c.size, c.source) for n, c in zip(names, known_calibration)]
    check_same_projections(result.rig, expected)
    assert any("as the camera centre" in n for n in result.notes)
    # the override: read as world -> camera, the same numbers put every camera somewhere else
    wrong = read_calibrations([path], translation="world-to-camera").cameras
    assert not np.allclose(wrong[0].t, known_calibration[0].t, atol=1.0)


def test_translation_override_on_an_opencv_file_of_camera_centres(tmp_path, known_calibration, spelled_writer,
                                                                  check_same_projections):
    centred = [type(c)(c.name, c.K, c.dist, c.R, -np.asarray(c.R).T @ c.t, c.size, c.source)
               for c in known_calibration]
    paths = []
    for c in centred:
        spelled_writer(tmp_path / f"{c.name}.yml", c, "short")
        paths.append(tmp_path / f"{c.name}.yml")
    result = import_rig(paths, options(translation="camera-centre"))
    check_same_projections(result.rig, known_calibration)


def test_xrprimer_camera_to_world_records_and_scalar_distortion(tmp_path, known_calibration, check_same_projections):
    records = []
    for c in known_calibration:
        R_c2w, d, K = np.asarray(c.R).T, np.asarray(c.dist), np.asarray(c.K)
        intrinsic = [[K[0, 0], 0.0, K[0, 2], 0.0], [0.0, K[1, 1], K[1, 2], 0.0], [0.0, 0.0, 0.0, 1.0],
                     [0.0, 0.0, 1.0, 0.0]]
        records.append({"class_name": "PinholeCameraParameter", "name": c.name, "intrinsic": intrinsic,
                        "extrinsic_r": R_c2w.tolist(), "extrinsic_t": (-R_c2w @ c.t).tolist(), "height": c.size[1],
                        "width": c.size[0], "world2cam": False, "convention": "opencv", "distortion_k1": d[0],
                        "distortion_k2": d[1], "distortion_k3": d[4], "distortion_p1": d[2], "distortion_p2": d[3]})
    paths = [_write(tmp_path / f"{r['name']}.json", r) for r in records]  # one file per camera, as XRPrimer dumps
    result = import_rig(paths, options())
    check_same_projections(result.rig, known_calibration)
    assert not any("camera centre" in n for n in result.notes)


def test_errors_name_the_file_and_the_record(tmp_path, known_calibration):
    bad = _write(tmp_path / "nothing.json", {"sequence": "x", "frames": [1, 2, 3]})
    with pytest.raises(RigError, match=r"nothing.json: no camera found in this JSON file"):
        read_calibrations([bad])
    broken = tmp_path / "broken.json"
    broken.write_text('{"cameras": [')
    with pytest.raises(RigError, match=r"broken.json: not valid JSON"):
        read_calibrations([broken])
    layout = panoptic_layout(known_calibration)
    del layout["cameras"][2]["R"]
    no_pose = _write(tmp_path / "no_pose.json", layout)
    with pytest.raises(RigError, match=r"no_pose.json: missing field cameras\[2\]\.rotation"):
        read_calibrations([no_pose])
    layout = aist_layout(known_calibration)
    layout[1]["name"] = layout[0]["name"]
    twice = _write(tmp_path / "twice.json", layout)
    with pytest.raises(RigError, match=r"twice.json: camera name\(s\) .* used by more than one record"):
        read_calibrations([twice])
    split = human36m_layout(known_calibration)
    split["1"]["k"] = _column(range(7))
    many = _write(tmp_path / "many.json", split)
    with pytest.raises(RigError, match=r"many.json: field 1\.k: expected at most 6 radial coefficients"):
        read_calibrations([many])
    with pytest.raises(RigError, match=r"--translation: must be one of"):
        read_calibrations([many], translation="centre")


def test_load_rig_points_foreign_json_to_rig_import(tmp_path, known_calibration):
    path = _write(tmp_path / "calibration_160224.json", panoptic_layout(known_calibration))
    with pytest.raises(RigError, match=r"convert it with `silpose rig import .*calibration_160224.json"):
        load_rig(path)


def test_cli_imports_a_panoptic_file(tmp_path, known_calibration):
    path = _write(tmp_path / "calibration_seq.json", panoptic_layout(known_calibration, extra_vga=2))
    out = tmp_path / "rig.json"
    res = CliRunner().invoke(build_app(), ["rig", "import", str(path), "--out", str(out), "--unit", "mm",
                                           "--cameras", "00_*", "--step", "0.2"])
    assert res.exit_code == 0, res.output
    assert load_rig(out).names == tuple(f"00_{i:02d}" for i in range(len(known_calibration)))
    res = CliRunner().invoke(build_app(), ["rig", "import", str(path), "--out", str(tmp_path / "r2.json"),
                                           "--cameras", "cam*"])
    assert res.exit_code != 0 and "--cameras: 'cam*' matches none" in res.output


def human36m_parameters_layout(calibration, subjects=("S1", "S9")):
    """Human3.6M's camera-parameters.json (karfly/human36m-camera-parameters): intrinsics per camera,
    extrinsics per subject and camera (world -> camera, t as a column). Subject S1 here has every camera
    moved 10 units along x, so picking the wrong subject shows."""
    out = {"intrinsics": {c.name: {"calibration_matrix": np.asarray(c.K).tolist(),
                                   "distortion": np.asarray(c.dist).tolist()} for c in calibration},
           "extrinsics": {}}
    for s in subjects:
        shift = np.array([10.0, 0.0, 0.0]) if s == "S1" else np.zeros(3)
        out["extrinsics"][s] = {c.name: {"R": np.asarray(c.R).tolist(), "t": _column(np.asarray(c.t) + shift)}
                                for c in calibration}
    return out


def test_human36m_intrinsics_and_per_subject_extrinsics(tmp_path, known_calibration, check_same_projections):
    path = _write(tmp_path / "camera-parameters.json", human36m_parameters_layout(known_calibration))
    sizes = ",".join(f"{c.name}={_size(c)}" for c in known_calibration)
    with pytest.raises(RigError, match=r"camera-parameters.json: the file holds the cameras' poses for 2 groups "
                                       r"\(S1, S9\): keep one with --cameras 'S1/\*'"):
        import_rig([path], options(image_size=sizes))
    result = import_rig([path], options(cameras="S9/*", image_size=sizes))
    check_same_projections(result.rig, known_calibration)  # plain camera names, subject S9's poses
    assert any("cameras of group S9 named" in n for n in result.notes)
    one = human36m_parameters_layout(known_calibration, subjects=("S9",))
    del one["intrinsics"][known_calibration[1].name]
    broken = _write(tmp_path / "broken-parameters.json", one)
    with pytest.raises(RigError, match=rf"the pose at extrinsics\.S9\.{known_calibration[1].name} has no intrinsics"):
        read_calibrations([broken])


def _write_video(path, size):
    import cv2

    path.parent.mkdir(parents=True, exist_ok=True)
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, size)
    for _ in range(2):
        out.write(np.zeros((size[1], size[0], 3), np.uint8))
    out.release()


def test_per_camera_image_sizes_and_dataset_video_names_next_to_the_file(tmp_path, known_calibration):
    layout = human36m_parameters_layout(known_calibration, subjects=("S9",))
    path = _write(tmp_path / "camera-parameters.json", layout)
    names = [c.name for c in known_calibration]
    w, h = known_calibration[0].size
    # one camera gets its size from the option, the others from videos named as Human3.6M names them
    # (Walking.<camera>.mp4) below the file
    for name in names[1:]:
        _write_video(tmp_path / "videos" / f"Walking.{name}.mp4", (w, h))
    rig = import_rig([path], options(image_size=f"{names[0]}={w}x{h}")).rig
    assert [(c.width, c.height) for c in rig] == [(w, h)] * len(names)
    with pytest.raises(RigError, match=r"--image-size: 'nope' is not a camera of the calibration"):
        import_rig([path], options(image_size=f"nope={w}x{h}"))
    with pytest.raises(RigError, match=r"--image-size: two sizes for the cameras not named"):
        import_rig([path], options(image_size=f"{w}x{h},{w}x{h}"))


def test_pose_nested_in_the_camera_record(tmp_path, known_calibration, check_same_projections):
    layout = {c.name: {"K": np.asarray(c.K).tolist(), "dist": np.asarray(c.dist).tolist(), "image_size": list(c.size),
                       "extrinsics": {"rvec": rotation_to_rvec(c.R).tolist(), "tvec": np.asarray(c.t).tolist()}}
              for c in known_calibration}
    path = _write(tmp_path / "cams.json", layout)
    check_same_projections(import_rig([path], options()).rig, known_calibration)
