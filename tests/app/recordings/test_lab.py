"""End to end on the generated lab recording: two walkers crossing in front of four cameras on one wall.

The recording (:mod:`silpose.datagen.lab`: lossy mask videos, and colour videos composited from the same
masks with an empty-room clip) and the model (a small one trained on a dataset rendered for the lab rig)
are session fixtures (``conftest.py``); Blender runs in spawned workers. Scores: :mod:`benchmarks.recording_scores`.
"""

import json

import cv2
import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from silpose.app.recordings.pipeline import RecordingOptions, run_recording
from silpose.datagen.lab import LAB_TRANSFORM, unpack_masks
from benchmarks.recording_scores import (clean_reference, joints_inside, read_rows, read_view_status, score_reference,
                                         score_rows)
from silpose.model.persistence import load_model
from silpose.shared.cli import build_app

pytestmark = pytest.mark.blender

#: cm the recording's world-frame joint error may exceed the clean per-person masks' (measured: see test)
WORLD_MARGIN_CM = 3.0
#: cm, the root error bound (measured: see test)
ROOT_BOUND_CM = 12.0


@pytest.fixture(scope="module")
def truth(lab):
    t = np.load(lab / "truth.npz")
    return {"joints": t["joints"], "masks": unpack_masks(t)}


@pytest.fixture(scope="module")
def run(lab, lab_model, tmp_path_factory):
    out = tmp_path_factory.mktemp("labout") / "out"
    res = CliRunner().invoke(build_app(), ["infer", str(lab_model), "--videos", str(lab / "masks"), "--masks",
                                           "--out", str(out), "--no-progress"])
    assert res.exit_code == 0, res.output
    return out, res.output, read_rows(out / "joints.parquet")


@pytest.fixture(scope="module")
def scores(run, truth):
    return score_rows(run[2], truth["joints"])


@pytest.fixture(scope="module")
def reference(lab_model, truth):
    return score_reference(clean_reference(load_model(lab_model), truth["masks"]), truth["joints"])


def test_writes_joints_overlays_and_floorplan(run, truth):
    out, output, rows = run
    n = len(truth["joints"])
    for name in ("joints.parquet", "joints.csv", "floorplan.png", "overlays/cam0.mp4", "overlays/cam3.mp4"):
        assert (out / name).is_file()
    cap = cv2.VideoCapture(str(out / "overlays" / "cam2.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == n
    assert f"2 person(s) over {n} frames" in output


def test_both_people_found_and_ids_never_swap(scores, truth):
    T, P = truth["joints"].shape[:2]
    assert scores["persons"] == 2 and scores["identity_switches"] == 0
    assert scores["paired"] == T * P and scores["false_rows"] == 0


def _merged(masks_f_k: np.ndarray, p: int) -> bool:
    """Person p's clean mask overlaps or touches (8-neighbours) another person's in this view: the recorded
    mask then holds both in one blob."""
    mine = cv2.dilate(masks_f_k[p].view(np.uint8), np.ones((3, 3), np.uint8)) > 0
    others = masks_f_k[[q for q in range(len(masks_f_k)) if q != p]].any(axis=0)
    return bool((mine & others).any())


def test_views_where_people_overlap_are_missing(run, scores, truth):
    out = run[0]
    t = pq.read_table(out / "joints.parquet")
    vs = np.array(t.column("view_status").to_pylist())
    paired = scores["per_row"]["paired"]
    frames = run[2]["frame"]
    merged_ok, merged, separate, separate_ok = 0, 0, 0, 0
    for i in np.flatnonzero(paired >= 0):
        for k in range(vs.shape[1]):
            m = _merged(truth["masks"][frames[i], :, k], paired[i])
            merged += m
            merged_ok += m and vs[i, k] == "ok"
            separate += not m
            separate_ok += (not m) and vs[i, k] == "ok"
    assert merged > 10 and merged_ok == 0  # an overlapping view is never used
    assert separate_ok >= 0.95 * separate  # and a clean one almost always is


def test_world_frame_error_within_a_measured_bound_of_clean_masks(scores, reference):
    """Measured (50 frames, model M 3 q 12 on 240 lab-rig walkers; 96 of 100 person-frames with joints):
    world-frame error 17.7 cm from the recording vs 17.6 cm from the clean per-person masks, root 6.2 vs 6.0 cm
    (the small model's root-relative error, 17.4 cm, dominates both). Colour videos: 20.5 cm, root 6.1 cm."""
    print("recording", {k: v for k, v in scores.items() if k != "per_row"}, "clean", reference)
    assert scores["with_joints"] >= 0.9 * scores["paired"]
    assert scores["world_error_cm"] <= reference["world_error_cm"] + WORLD_MARGIN_CM
    assert scores["root_error_cm"] <= ROOT_BOUND_CM
    assert scores["views_at_least"][1] >= 0.9


def test_joints_fitted_inside_the_silhouettes_of_the_views_used(run, scores, truth, lab, lab_model, reference,
                                                                tmp_path):
    """The silhouette fit (``silpose.app.recordings.silhouette_fit``, on by default) against the same run without it
    (``--no-silhouette-fit``), scored against each walker's own clean masks in the views each row used (2 px): more
    joints inside, and the world-frame error no worse. Measured here (50 frames, the small model): 0.845 -> 0.997 of
    the joints inside, world error 14.60 -> 14.25 cm."""
    out = run[0]
    plain = tmp_path / "plain"
    res = CliRunner().invoke(build_app(), ["infer", str(lab_model), "--videos", str(lab / "masks"), "--masks",
                                           "--out", str(plain), "--no-progress", "--no-silhouette-fit",
                                           "--overlays", "none"])
    assert res.exit_code == 0, res.output
    plain_rows = read_rows(plain / "joints.parquet")
    plain_scores = score_rows(plain_rows, truth["joints"])
    cameras = list(load_model(lab_model).rig_)
    fitted = joints_inside(run[2], read_view_status(out / "joints.parquet"), scores["per_row"]["paired"],
                           truth["masks"], cameras)
    before = joints_inside(plain_rows, read_view_status(plain / "joints.parquet"), plain_scores["per_row"]["paired"],
                           truth["masks"], cameras)
    print("inside", before["share"], "->", fitted["share"], "world cm", plain_scores["world_error_cm"], "->",
          scores["world_error_cm"])
    assert fitted["joints"] == before["joints"] > 500  # the same rows and views: only the joints moved
    assert fitted["share"] >= before["share"] + 0.03 and fitted["share"] >= 0.95
    assert scores["world_error_cm"] <= plain_scores["world_error_cm"] + 0.2


def test_joints_in_the_calibration_frame(lab, lab_model, tmp_path):
    """The model's rig carries the lab's transform (as an imported rig does): joints_calibration are the lab's
    own coordinates, checked by projecting them with the rig read from the lab's OpenCV files."""
    model = load_model(lab_model)
    object.__setattr__(model.rig_, "transform", LAB_TRANSFORM)
    out = tmp_path / "o"
    run_recording(model, lab / "masks", out, RecordingOptions(masks=True, overlays=False, max_steps=8))
    t = pq.read_table(out / "joints.parquet")
    assert json.loads(t.schema.metadata[b"silpose_recording"])["transform"]["scale"] == 0.001
    ok = np.array(t.column("status").to_pylist()) == "ok"
    j = np.array(t.column("joints").to_pylist())[ok]
    jc = np.array(t.column("joints_calibration").to_pylist())[ok]
    assert np.allclose(jc, LAB_TRANSFORM.to_calibration(j), atol=0.5)  # float32 millimetres
    assert (jc[..., 2] < 50).all() and (jc[..., 2] > -2200).all()  # z down: the body is above the floor, negative
    calib = [_read_lab_camera(f) for f in sorted((lab / "calibration").glob("*.yml"))]  # the lab's cameras, metres
    for cam_c, cam in zip(calib, model.rig_):
        assert np.allclose(cam_c.project(jc * 0.001), cam.project(j), atol=0.05)


def test_colour_videos_with_an_empty_room_clip(lab_colour, lab_model, truth, tmp_path):
    s = run_recording(str(lab_model), lab_colour / "colour", tmp_path / "o",
                      RecordingOptions(background=lab_colour / "empty", overlays=False))
    sc = score_rows(read_rows(tmp_path / "o" / "joints.parquet"), truth["joints"])
    print("colour", {k: v for k, v in sc.items() if k != "per_row"})
    assert s.n_persons == 2 and sc["identity_switches"] == 0 and sc["false_rows"] == 0
    assert sc["paired"] >= 0.95 * truth["joints"].shape[0] * 2
    assert sc["root_error_cm"] <= ROOT_BOUND_CM


def _read_lab_camera(path):
    """A lab calibration file read back with OpenCV alone (an independent reader), translation in metres."""
    import cv2

    from silpose.shared.camera import Camera

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        K = fs.getNode("camera_matrix").mat()
        R, _ = cv2.Rodrigues(fs.getNode("rvec").mat())
        t = fs.getNode("tvec").mat().ravel() * 0.001
        w, h = int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real())
        dist = fs.getNode("distortion_coefficients").mat().ravel()
    finally:
        fs.release()
    return Camera(name=path.stem, K=K, R=R, t=t, width=w, height=h, dist=dist)
