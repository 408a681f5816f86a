"""``silpose infer MODEL --videos DIR``: outputs, statuses and bad input, on cylinder "people" (no Blender).

The model is a tiny one fitted on stick figures of the lab rig (its joints are meaningless): these tests
check what the workflow finds, writes and refuses, not the poses (``test_lab.py`` does).
"""

import json
import threading

import cv2

import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from silpose.app.recordings.pipeline import RecordingOptions, run_recording
from silpose.shared.cli import build_app


def _invoke(*args):
    return CliRunner().invoke(build_app(), [str(a) for a in args])


def _rows(out):
    t = pq.read_table(out / "joints.parquet")
    return t, {c: t.column(c).to_pylist() for c in ("frame", "person", "status", "n_views", "view_status")}


def test_cli_writes_joints_overlays_floorplan(tiny_model_file, two_cylinders, tmp_path):
    out = tmp_path / "out"
    res = _invoke("infer", tiny_model_file, "--videos", two_cylinders, "--masks", "--out", out, "--no-progress",
                  "--contours")
    assert res.exit_code == 0, res.output
    assert "2 person(s) over 20 frames" in res.output
    for name in ("joints.parquet", "joints.csv", "floorplan.png", "summary.json", "overlays/cam0.mp4", "overlays/cam3.mp4"):
        assert (out / name).is_file(), name
    assert not list(out.glob(".*.tmp"))  # no temporary files left (the output-folder marker stays)
    t, r = _rows(out)
    assert set(r["person"]) == {1, 2} and len(t) == 40 and set(r["status"]) <= {"ok", "no usable view"}
    assert r["status"].count("ok") >= 32  # no view only while they cross in front of every camera
    assert sorted(r["frame"]) == sorted(list(range(20)) * 2)
    meta = json.loads(t.schema.metadata[b"silpose_recording"])
    assert meta["cameras"] == ["cam0", "cam1", "cam2", "cam3"] and meta["fps"] == pytest.approx(25.0)
    joints = np.array(t.column("joints").to_pylist())
    root = np.array(t.column("root").to_pylist())
    ok = np.array(r["status"]) == "ok"
    assert np.isfinite(joints[ok]).all() and np.isnan(joints[~ok]).all()  # never joints from nothing
    assert np.allclose(joints[ok, 0], root[ok], atol=1e-5)  # pelvis = root, in the room
    contours = np.array(t.column("contours_px").to_pylist())
    merged = np.array(r["view_status"]) == "merged"
    assert contours.shape == (40, 4, 40, 2) and merged[ok].any()
    assert np.isfinite(contours[ok]).all()  # every view's contour in pixels, the missing (merged) ones projected
    floor = np.c_[t.column("floor_x").to_numpy(), t.column("floor_y").to_numpy()]
    assert np.linalg.norm(root[ok, :2] - floor[ok], axis=1).max() < 0.5
    cap = cv2.VideoCapture(str(out / "overlays" / "cam1.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 20 and int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)) == 644
    summary = json.loads((out / "summary.json").read_text())
    assert summary["persons"] == 2 and summary["frames"] == 20 and summary["rows"]["ok"] == r["status"].count("ok")
    inside = t.column("inside").to_numpy(zero_copy_only=False)
    assert np.isnan(inside[~ok]).all() and ((inside[ok] >= 0) & (inside[ok] <= 1)).all()
    assert summary["inside"] == pytest.approx(float(np.nanmean(inside)), abs=1e-4) and summary["inside"] > 0.5
    assert "joints inside their own silhouettes in the views used" in res.output


def test_ids_follow_each_cylinder(tiny_model, two_cylinders, tmp_path):
    s = run_recording(tiny_model, two_cylinders, tmp_path / "o", RecordingOptions(masks=True, overlays=False))
    t, r = _rows(tmp_path / "o")
    y = t.column("floor_y").to_numpy()
    for person in (1, 2):
        ys = y[np.array(r["person"]) == person]
        assert np.ptp(ys) < 0.2  # one id keeps to one walker's line (y -0.6 or 0.7)
    assert s.n_persons == 2 and sum(s.views_hist) == 40 and s.views_hist[4] > 0


def test_small_chunks_and_no_hypotheses_write_the_same_rows(tiny_model, two_cylinders, tmp_path):
    """Chunks of 3 steps (each decided once the next is inferred, the last with none ahead) write every person-frame
    the default chunks write; without hypotheses every row answers with the posterior mean (hypothesis slot 0),
    with them each inferred row names its chosen slot."""
    keys = {}
    for name, opt in (("default", RecordingOptions(masks=True, overlays=False)),
                      ("small", RecordingOptions(masks=True, overlays=False, chunk=3)),
                      ("mean", RecordingOptions(masks=True, overlays=False, chunk=3, hypotheses=0))):
        run_recording(tiny_model, two_cylinders, tmp_path / name, opt)
        t, r = _rows(tmp_path / name)
        keys[name] = sorted(zip(r["frame"], r["person"]))
        ok = np.array(r["status"]) == "ok"
        slot = t.column("hypothesis").to_numpy()
        assert ok.sum() > 20
        assert (slot[ok] == 0).all() if name == "mean" else (slot[ok] >= 1).all()
    assert keys["small"] == keys["default"] == keys["mean"] and len(keys["default"]) == 40


def test_missing_camera_black_frames_and_a_blob_in_one_camera(rig, tiny_model, tools, tmp_path):
    videos = tmp_path / "v"
    track = tools.walk((-1.0, -0.5), (1.0, -0.5), 12)
    frames = np.stack([tools.cylinder_masks(rig, [p]) for p in track], 1)  # (K, 12, H, W)
    frames[2, :, 100:160, 40:70] = 255  # a blob only cam2 sees: nobody on the floor, nobody's view
    frames[1, 5] = 0  # an all-black frame in cam1
    videos.mkdir()
    for k in range(3):  # no video for cam3
        tools.write_video(videos / f"cam{k}.mp4", frames[k])
    s = run_recording(tiny_model, videos, tmp_path / "o", RecordingOptions(masks=True, overlays=False))
    assert s.n_persons == 1 and any("cam3" in w for w in s.warnings)
    t, r = _rows(tmp_path / "o")
    vs = np.array(r["view_status"])
    assert (vs[:, 3] == "no video").all() and (vs[:, [0, 2]] == "ok").all()
    assert list(vs[:, 1]) == ["ok"] * 5 + ["empty mask"] + ["ok"] * 6
    assert r["n_views"] == [3] * 5 + [2] + [3] * 6 and set(r["status"]) == {"ok"}
    assert s.camera_status["cam3"]["no video"] == 12 and s.camera_status["cam1"]["empty mask"] == 1


def test_nobody_anywhere_writes_no_rows(rig, tiny_model, tools, tmp_path):
    videos = tmp_path / "v"
    videos.mkdir()
    for cam in rig:
        tools.write_video(videos / f"{cam.name}.mp4", np.zeros((6, 486, 644), np.uint8))
    s = run_recording(tiny_model, videos, tmp_path / "o", RecordingOptions(masks=True, overlays=False))
    t, _ = _rows(tmp_path / "o")
    assert len(t) == 0 and s.n_persons == 0 and s.camera_status["cam0"]["empty mask"] == 6
    assert any("nobody stood on the floor that 2 cameras see" in w for w in s.warnings), s.warnings


def test_masks_stored_as_0_1_or_inverted_are_diagnosed(rig, tiny_model, tools, tmp_path):
    """Two common mask-video mistakes end in "nobody was found"; the warnings say why, naming the video."""
    track = tools.walk((-1.0, -0.5), (1.0, -0.5), 8)
    frames = np.stack([tools.cylinder_masks(rig, [p]) for p in track], 1)  # (K, 8, H, W) 0/255
    videos = tmp_path / "v"
    videos.mkdir()
    for k, cam in enumerate(rig):
        f = frames[k] // 255 if k == 0 else (255 - frames[k] if k == 1 else frames[k])  # cam0: 0/1, cam1: inverted
        tools.write_video(videos / f"{cam.name}.mp4", f)
    s = run_recording(tiny_model, videos, tmp_path / "o", RecordingOptions(masks=True, overlays=False))
    lines = {w.split(":")[0]: w for w in s.warnings}
    assert "foreground is stored as 1 (not 255)" in lines["cam0.mp4"] and "no foreground in 8 of 8" in lines["cam0.mp4"]
    assert "inverted" in lines["cam1.mp4"] and "8 of 8 frames" in lines["cam1.mp4"]
    assert "cam2.mp4" not in lines and "cam3.mp4" not in lines
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["warnings"] == s.warnings


def test_a_detection_that_never_becomes_a_person_leaves_no_rows(rig, tiny_model, tiny_model_file, tools, tmp_path):
    videos = tmp_path / "v"
    videos.mkdir()
    frames = np.zeros((len(rig), 10, 486, 644), np.uint8)
    frames[:, 4] = tools.cylinder_masks(rig, [(0.2, 0.1)])  # someone in one frame only
    for k, cam in enumerate(rig):
        tools.write_video(videos / f"{cam.name}.mp4", frames[k])
    s = run_recording(tiny_model, videos, tmp_path / "o", RecordingOptions(masks=True, overlays=False))
    assert s.n_persons == 0 and _rows(tmp_path / "o")[0].num_rows == 0
    # the warning names the cause (a few moments far apart, as CMU Panoptic's demo frames) and the option
    assert any("someone stood on the floor in 1 of 10 frames" in w and "--min-hits 1" in w for w in s.warnings), s.warnings
    res = _invoke("infer", tiny_model_file, "--videos", videos, "--masks", "--min-hits", "1", "--overlays", "none",
                  "--out", tmp_path / "o1", "--no-progress")
    assert res.exit_code == 0 and "1 person(s) over 10 frames" in res.output, res.output
    assert _rows(tmp_path / "o1")[0].num_rows >= 1


def test_people_beyond_a_small_workspace_are_found(rig, tiny_model, tools, tmp_path):
    """An imported rig's workspace can be the small square every camera sees whole (CMU Panoptic's five cameras:
    0.4 m) while people stand a metre or two away: they are looked for wherever the cameras look
    (floor.capture_area), not on the workspace plus a margin."""
    import copy

    from silpose.shared.rig_frame import Workspace

    model = copy.copy(tiny_model)
    model.rig_ = rig.with_workspace(Workspace([0.0, 0.0], [0.4, 0.4]))
    videos = tmp_path / "v"
    write = tools.write_mask_videos
    write(videos, rig, [tools.walk((1.2, 0.9), (1.4, 1.0), 12), tools.walk((-1.3, -0.6), (-1.1, -0.9), 12)])
    s = run_recording(model, videos, tmp_path / "o", RecordingOptions(masks=True, overlays=False))
    assert s.n_persons == 2, s.warnings
    t, _ = _rows(tmp_path / "o")
    xy = np.stack([t.column("floor_x").to_numpy(), t.column("floor_y").to_numpy()], 1)
    xy = xy[np.isfinite(xy).all(axis=1)]
    assert len(xy) >= 2 * 8 and np.all(np.abs(xy).max(axis=1) > 0.7)  # all beyond the workspace plus the margin


def _colour_walk(rig, tools, videos, n: int) -> np.ndarray:
    """Colour videos in ``videos``: 6 empty-room frames, then a cylinder walking across in ``n`` frames, composited over
    each camera's textured room; returns the (n, 2) floor points walked."""
    from silpose.segment.composite import background_frames, composite_frame, room

    videos.mkdir()
    where = tools.walk((-0.8, 0.2), (0.8, 0.2), n)
    for k, cam in enumerate(rig):
        size = (cam.width, cam.height)
        clean = room(k, size)
        people = [composite_frame(tools.cylinder_masks(rig, [p])[k] > 0, k, i, clean=clean) for i, p in enumerate(where)]
        tools.write_video(videos / f"{cam.name}.mp4", np.concatenate([background_frames(k, size, 6), np.stack(people)]))
    return where


def test_colour_videos_with_first_frames_as_background(rig, tiny_model, tools, tmp_path):
    videos = tmp_path / "v"
    where = _colour_walk(rig, tools, videos, 8)
    s = run_recording(tiny_model, videos, tmp_path / "o", RecordingOptions(background_frames=6, overlays=False))
    t, r = _rows(tmp_path / "o")
    assert s.n_persons == 1 and s.n_steps == 8 and min(r["frame"]) >= 6  # frames keep the video's numbering
    floor = np.c_[t.column("floor_x").to_numpy(), t.column("floor_y").to_numpy()]
    truth = where[np.array(r["frame"]) - 6]
    assert np.linalg.norm(floor - truth, axis=1).max() < 0.1


def test_colour_segmentation_started_in_the_reader_threads_changes_nothing(rig, tiny_model, tools, tmp_path,
                                                                         monkeypatch):
    """Colour videos: each frame's first segmentation steps run in its camera's reader thread
    (``ColourSegmenter.candidates``); the joints file is the one of a run without reader threads, where the run's
    thread does every step."""
    from silpose.app.recordings.silhouettes import ColourSegmenter

    videos = tmp_path / "v"
    _colour_walk(rig, tools, videos, 12)
    threads = set()
    real = ColourSegmenter.candidates
    monkeypatch.setattr(ColourSegmenter, "candidates",
                        lambda self, c, img: threads.add(threading.current_thread().name) or real(self, c, img))
    tables = []
    for i, readers in enumerate((True, False)):
        run_recording(tiny_model, videos, tmp_path / f"o{i}",
                      RecordingOptions(background_frames=6, overlays=False, reader_threads=readers))
        tables.append(pq.read_table(tmp_path / f"o{i}" / "joints.parquet"))
        if readers:
            assert threads and all(t.startswith("read-") for t in threads)
    assert tables[0].num_rows == tables[1].num_rows > 0
    for col in tables[0].column_names:
        a, b = _flat(tables[0].column(col)), _flat(tables[1].column(col))
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), col


def test_colour_videos_with_the_recordings_own_median_as_background(rig, tiny_model_file, tools, tmp_path):
    """No empty room at all: a walker crossing the whole room, the background is the per-pixel median of
    frames spread over the recording (``--background median``); the walker is found in every frame."""
    from silpose.segment.composite import composite_frame, room

    videos = tmp_path / "v"
    videos.mkdir()
    where = tools.walk((-1.2, 0.2), (1.2, 0.2), 16)
    for k, cam in enumerate(rig):
        clean = room(k, (cam.width, cam.height))
        tools.write_video(videos / f"{cam.name}.mp4", np.stack(
            [composite_frame(tools.cylinder_masks(rig, [p])[k] > 0, k, i, clean=clean) for i, p in enumerate(where)]))
    res = _invoke("infer", tiny_model_file, "--videos", videos, "--background", "median", "--out", tmp_path / "o",
                  "--no-progress", "--overlays", "none")
    assert res.exit_code == 0, res.output
    t, r = _rows(tmp_path / "o")
    assert set(r["person"]) == {1} and sorted(r["frame"]) == list(range(16))
    assert r["status"].count("ok") >= 14
    floor = np.c_[t.column("floor_x").to_numpy(), t.column("floor_y").to_numpy()]
    assert np.linalg.norm(floor - where[np.array(r["frame"])], axis=1).max() < 0.1


def test_someone_standing_still_under_a_median_background_is_diagnosed(rig, tiny_model, tools, tmp_path):
    """Pose2Sim's demo: one person balancing in place for 1.7 s and no empty-room footage (here 4 frames). The recording's
    median is then that person, nobody is found, and the warning says why and what to give instead."""
    from pathlib import Path

    from silpose.segment.composite import composite_frame, room

    videos = tmp_path / "v"
    videos.mkdir()
    for k, cam in enumerate(rig):
        clean = room(k, (cam.width, cam.height))
        mask = tools.cylinder_masks(rig, [(0.3, 0.1)])[k] > 0
        tools.write_video(videos / f"{cam.name}.mp4", np.stack([composite_frame(mask, k, i, clean=clean)
                                                                 for i in range(4)]))
    s = run_recording(tiny_model, videos, tmp_path / "o", RecordingOptions(background=Path("median"), overlays=False))
    assert s.n_persons == 0
    assert any("nobody was found" in w and "hardly moves" in w and "--background DIR" in w for w in s.warnings)


@pytest.mark.parametrize("args, message", [
    (["--masks", "--background-frames", "5"], "mask videos need no background"),
    ([], "colour videos need a background"),
    (["--background", "empty", "--background-frames", "3"], "give one background"),
    (["--masks", "--offsets", "camZ=1"], "camera 'camZ' is not in the rig"),
])
def test_bad_options_are_one_line_errors(tiny_model_file, two_cylinders, tmp_path, args, message):
    res = _invoke("infer", tiny_model_file, "--videos", two_cylinders, *args, "--out", tmp_path / "o", "--no-progress")
    assert res.exit_code != 0 and message in res.output
    assert res.output.strip().count("\n") == 0 and "Traceback" not in res.output


def test_videos_excludes_other_inputs(tiny_model_file, two_cylinders, tmp_path):
    res = _invoke("infer", tiny_model_file, tmp_path, "--videos", two_cylinders, "--masks")
    assert res.exit_code != 0 and "not INPUT and --videos" in res.output
    res = _invoke("infer", tiny_model_file, tmp_path, "--masks")
    assert res.exit_code != 0 and "--masks needs --videos" in res.output
    res = _invoke("infer", tiny_model_file, "--frames", two_cylinders, "--min-hits", "1")
    assert res.exit_code != 0 and "--min-hits is for several people" in res.output


def test_a_video_shorter_than_its_header_is_a_missing_view_from_there_on(rig, tiny_model, tools, tmp_path, monkeypatch):
    from silpose.app.recordings import sources

    videos = tmp_path / "v"
    tools.write_mask_videos(videos, rig, [tools.walk((-0.5, 0.0), (0.5, 0.0), 10)])
    real = sources.CameraReader.read

    def read(self):  # cam1 stops decoding after 6 frames (a truncated file)
        if self.source.camera == "cam1" and self.index >= 6:
            return None
        return real(self)

    monkeypatch.setattr(sources.CameraReader, "read", read)
    s = run_recording(tiny_model, videos, tmp_path / "o", RecordingOptions(masks=True, overlays=True))
    assert s.n_steps == 10 and any("cam1.mp4 ended after 6 frames (expected 10)" in w for w in s.warnings)
    assert s.camera_status["cam1"]["video ended"] == 4 and s.camera_status["cam0"]["video ended"] == 0
    assert (tmp_path / "o" / "joints.parquet").is_file() and (tmp_path / "o" / "overlays" / "cam0.mp4").is_file()


def test_offsets_synchronise_a_camera_that_started_late(rig, tiny_model, tools, tmp_path):
    videos = tmp_path / "v"
    videos.mkdir()
    track = tools.walk((-0.8, 0.0), (0.8, 0.0), 10)
    frames = np.stack([tools.cylinder_masks(rig, [p]) for p in track], 1)  # (K, 10, H, W)
    for k, cam in enumerate(rig):
        f = frames[k]
        if cam.name == "cam1":  # two black frames first: cam1's frame i + 2 is the others' frame i
            f = np.concatenate([np.zeros((2,) + f.shape[1:], np.uint8), f])
        tools.write_video(videos / f"{cam.name}.mp4", f)
    plain = run_recording(tiny_model, videos, tmp_path / "a", RecordingOptions(masks=True, overlays=False))
    shifted = run_recording(tiny_model, videos, tmp_path / "b", RecordingOptions(masks=True, overlays=False,
                                                                                  offsets="cam1=2"))
    assert plain.camera_status["cam1"]["empty mask"] == 2 and shifted.camera_status["cam1"]["empty mask"] == 0
    assert shifted.n_steps == 10 and shifted.views_hist[4] == 10
    t = pq.read_table(tmp_path / "b" / "joints.parquet")
    assert t.column("frame").to_pylist() == list(range(10))


def test_camera_threads_change_nothing(tiny_model, two_cylinders, tmp_path):
    """Per-camera worker threads (threads > 0) give the same file as everything in one thread (threads = 0).
    (Another chunk size batches other rows together for inference, which may change the last bits.)"""
    tables = []
    for i, (threads, chunk) in enumerate(((0, 2), (2, 2), (4, 2))):
        out = tmp_path / f"out{i}"
        run_recording(tiny_model, two_cylinders, out, RecordingOptions(masks=True, overlays=False, threads=threads,
                                                                       chunk=chunk))
        tables.append(pq.read_table(out / "joints.parquet"))
    for other in tables[1:]:
        assert other.column_names == tables[0].column_names and other.num_rows == tables[0].num_rows > 0
        for col in tables[0].column_names:
            a, b = _flat(tables[0].column(col)), _flat(other.column(col))
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), col


def test_the_camera_pool_is_left_out_below_three_cores(monkeypatch):
    """Without ``threads``: no camera pool on 1 or 2 cores; above, one thread per camera up to the core count (less
    two when the cameras decode in reader threads of their own)."""
    import os

    from silpose.app.recordings.pipeline import default_camera_threads

    want = {(1, False): 0, (2, False): 0, (2, True): 0, (3, False): 3, (3, True): 1, (4, False): 4, (4, True): 2,
            (8, False): 4, (8, True): 4}
    for (cores, readers), n in want.items():
        monkeypatch.setattr(os, "cpu_count", lambda c=cores: c)
        assert default_camera_threads(4, readers) == n, (cores, readers)


def test_mask_videos_decode_in_reader_threads_only_on_two_cores(monkeypatch):
    """Without ``reader_threads``: colour videos always decode in reader threads; mask videos only where a second
    core is free and no camera pool decodes ahead (2 cores)."""
    import os

    from silpose.app.recordings.pipeline import default_reader_threads

    for cores, masks in ((1, False), (1, True), (2, True), (3, True), (8, True), (2, False), (8, False)):
        monkeypatch.setattr(os, "cpu_count", lambda c=cores: c)
        assert default_reader_threads(masks) == (not masks or cores == 2), (cores, masks)


def _flat(column) -> np.ndarray:
    """A Parquet column's values as one flat numpy array (nested fixed-size lists unrolled)."""
    x = column.combine_chunks()
    while str(x.type).startswith("fixed_size_list"):
        x = x.flatten()
    return x.to_numpy(zero_copy_only=False)


def test_mask_videos_default_to_plain_inference(tiny_model, two_cylinders, tmp_path):
    """--videos --masks: robust inference and the visual-hull cut are off unless asked for (RecordingOptions.robust,
    .carve None)."""
    tables = {}
    for name, robust in (("default", None), ("plain", False), ("robust", True)):
        run_recording(tiny_model, two_cylinders, tmp_path / name,
                      RecordingOptions(masks=True, overlays=False, threads=0, robust=robust))
        tables[name] = pq.read_table(tmp_path / name / "joints.parquet")
    same = [np.array_equal(_flat(tables["default"].column(c)), _flat(tables["plain"].column(c)),
                           equal_nan=_flat(tables["plain"].column(c)).dtype.kind == "f")
            for c in tables["plain"].column_names]
    assert all(same)
    assert not np.array_equal(_flat(tables["robust"].column("joints")), _flat(tables["plain"].column("joints")),
                              equal_nan=True)
    assert np.isnan(_flat(tables["default"].column("view_cut"))).all()  # nor are mask videos carved (.hull)


def test_a_refused_recording_leaves_no_output_folder(tiny_model_file, tmp_path):
    """Colour videos without a background are refused before any frame: --out is not left behind holding
    only silpose's marker, and the error is the only line."""
    from typer.testing import CliRunner

    from silpose.shared.cli import build_app

    videos = tmp_path / "videos"
    videos.mkdir()
    out = tmp_path / "out"
    res = CliRunner().invoke(build_app(), ["infer", str(tiny_model_file), "--videos", str(videos), "--out", str(out)])
    assert res.exit_code == 2
    assert res.stderr.count("\n") == 1 and res.stderr.startswith("silpose infer: error: "), res.stderr
    assert not out.exists()


def _mjpg_videos(folder, rig, tools, n):
    """Mask videos ``<camera>.avi`` (MJPG: an AVI whose frames still decode when the file is cut) of one
    cylinder walking across the room, n frames."""
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    frames = np.stack([tools.cylinder_masks(rig, [p]) for p in tools.walk((-0.8, -0.3), (0.8, 0.3), n)], 1)
    for k, cam in enumerate(rig):
        w = cv2.VideoWriter(str(folder / f"{cam.name}.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25.0,
                            (cam.width, cam.height), isColor=False)
        for f in frames[k]:
            w.write(f)
        w.release()


def test_a_truncated_camera_file_loses_only_that_camera(rig, tiny_model, tools, tmp_path, capfd):
    """One of four mask videos cut to a third of its bytes: the other three cameras go on to the end; the cut
    camera is "video ended" for the rest, its decoder noise stays off the terminal and is summarised in one
    line. (Before: the run stopped at the cut camera's last frame, and FFmpeg printed "overread" lines.)"""
    n = 24
    videos = tmp_path / "v"
    _mjpg_videos(videos, rig, tools, n)
    cut = videos / "cam2.avi"
    data = cut.read_bytes()
    cut.write_bytes(data[: len(data) // 3])
    s = run_recording(tiny_model, videos, tmp_path / "o", RecordingOptions(masks=True, overlays=False))
    err = capfd.readouterr().err
    ended = s.camera_status["cam2"]["video ended"]
    assert s.n_steps == n and 0 < ended < n  # every step processed; cam2 lost only after its cut
    assert all(s.camera_status[c]["video ended"] == 0 for c in ("cam0", "cam1", "cam3"))
    assert sum(s.views_hist) >= n - 3  # the walker is still found in the frames after the cut
    assert any("cam2.avi: decoding stopped at frame" in w and f"of the {n}" in w for w in s.warnings)
    assert "overread" not in err and "@ 0x" not in err


def test_an_unreadable_camera_file_is_a_missing_view_in_every_frame(rig, tiny_model, tools, tmp_path):
    videos = tmp_path / "v"
    tools.write_mask_videos(videos, rig, [tools.walk((-0.5, 0.0), (0.5, 0.0), 8)])
    (videos / "cam3.mp4").write_bytes(b"not a video" * 50)
    s = run_recording(tiny_model, videos, tmp_path / "o", RecordingOptions(masks=True, overlays=False))
    assert s.n_steps == 8 and s.camera_status["cam3"]["no video"] == 8
    assert any(w.startswith(str(videos / "cam3.mp4") + ": OpenCV (FFmpeg) cannot open this video")
               and w.endswith("a missing view in every frame") for w in s.warnings)
