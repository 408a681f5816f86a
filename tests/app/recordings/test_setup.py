"""A colour run's set-up done side by side (``silpose infer --videos``): the videos probed in threads, the room
views and the plates' fits as separate tasks of one pool, the cameras' readers opened before the backgrounds are
learnt. Each gives what the one-after-the-other way gives (that way is what a 1-CPU machine runs)."""

from __future__ import annotations

import os
import threading

import cv2
import numpy as np
import pytest

from silpose.app.errors import RecordingError
from silpose.app.recordings.pipeline import RecordingOptions, run_recording
from silpose.app.recordings.silhouettes import at_size, background_from_clips
from silpose.app.recordings.sources import open_recording, probe_all
from silpose.segment.composite import background_frames, room

#: the empty-room clip's camera sat 1 % closer and a few pixels off (a 322x242 picture)
NUDGE = np.array([[1.01, 0.0, 3.0], [0.0, 1.01, 2.0]])


def _one_cpu(monkeypatch):
    monkeypatch.setattr(os, "cpu_count", lambda: 1)


def test_videos_probed_side_by_side_are_those_probed_one_by_one(rig, tools, tmp_path, monkeypatch):
    sizes = {"cam0": (644, 486), "cam1": (322, 242), "cam2": (644, 486)}  # cam1 stored at half size
    lengths = {"cam0": 7, "cam1": 5, "cam2": 9}
    for cam, (w, h) in sizes.items():
        tools.write_video(tmp_path / f"{cam}.mp4", np.full((lengths[cam], h, w, 3), 60, np.uint8))
    (tmp_path / "cam3.mp4").write_bytes(b"not a video")
    entries = {c: tmp_path / f"{c}.mp4" for c in rig.names}
    found = probe_all(entries, rig.names)
    assert [type(s).__name__ for s in found] == ["CameraSource"] * 3 + ["RecordingError"]
    assert [(s.camera, s.width, s.height, s.n_frames) for s in found[:3]] == \
        [(c, *sizes[c], lengths[c]) for c in ("cam0", "cam1", "cam2")]
    assert "cam3.mp4" in str(found[3])
    rec = open_recording(tmp_path, rig)
    _one_cpu(monkeypatch)
    assert probe_all(entries, rig.names)[:3] == found[:3]
    ref = open_recording(tmp_path, rig)
    assert rec.sources == ref.sources and rec.missing == ref.missing == ("cam3",)
    assert rec.warnings == ref.warnings and rec.n_steps == ref.n_steps == 9


def _nudged_room(rig, tools, tmp_path, n: int = 10):
    """Colour videos (a dark box crossing each camera's textured room) and empty-room clips shot by a nudged camera,
    at half the lab rig's size."""
    (tmp_path / "colour").mkdir()
    (tmp_path / "empty").mkdir()
    size = (322, 242)
    for k, cam in enumerate(rig):
        clean = np.clip(room(k, size), 0, 255).astype(np.uint8)
        frames = np.repeat(clean[None], n, axis=0)
        for f in range(n):
            frames[f, 80:200, 20 + 25 * f:60 + 25 * f] = (40, 30, 50)
        tools.write_video(tmp_path / "colour" / f"{cam.name}.mp4", frames)
        empty = np.stack([cv2.warpAffine(e, NUDGE, size, borderMode=cv2.BORDER_REFLECT)
                          for e in background_frames(k, size, 6)])
        tools.write_video(tmp_path / "empty" / f"{cam.name}.mp4", empty)
    return tmp_path / "colour", tmp_path / "empty"


def test_room_views_as_tasks_of_their_own_learn_the_backgrounds_of_one_camera_after_the_other(rig, tools, tmp_path,
                                                                                           monkeypatch):
    videos, empty = _nudged_room(rig, tools, tmp_path)
    rec = open_recording(videos, rig)
    work = {c: (161, 122) for c in rig.names}  # the working size: every frame shrunk
    sources = {c: at_size(s, work[c]) for c, s in rec.sources.items()}
    side_by_side = background_from_clips(empty, rig, list(sources), {}, work, sources).models
    _one_cpu(monkeypatch)  # one camera after the other, each room view computed inside its fit
    one_by_one = background_from_clips(empty, rig, list(sources), {}, work, sources).models
    for c in rig.names:
        a, b = side_by_side[c], one_by_one[c]
        assert a.plate_warp is not None  # the nudge was found: the room view mattered
        np.testing.assert_array_equal(a.plate_warp, b.plate_warp)
        assert a.min_std == b.min_std > 2.0  # raised by the plate's mismatch with the room view
        np.testing.assert_array_equal(a.colour_mean_, b.colour_mean_)
        np.testing.assert_array_equal(a.colour_std_, b.colour_std_)


def test_readers_opened_before_the_backgrounds_are_closed_when_learning_fails(tiny_model, tools, tmp_path):
    videos, empty = _nudged_room(tiny_model.rig_, tools, tmp_path, n=4)
    (empty / "cam2.mp4").unlink()
    before = {t for t in threading.enumerate() if t.name.startswith("read-")}
    with pytest.raises(RecordingError, match="no empty-room clip for camera"):
        run_recording(tiny_model, videos, tmp_path / "out", RecordingOptions(background=empty, overlays=False))
    left = {t for t in threading.enumerate() if t.name.startswith("read-") and t.is_alive()} - before
    assert not left, f"reader threads left running: {sorted(t.name for t in left)}"


def _decoded(path, first, n):
    cap = cv2.VideoCapture(str(path))
    frames = [cap.read()[1] for _ in range(first + n)][first:]
    cap.release()
    return np.stack(frames).astype(np.float64)


def test_a_plate_longer_than_a_chunk_is_fitted_once_from_the_frames_around_its_middle(rig, tools, tmp_path,
                                                                                    monkeypatch):
    """A 70-frame empty-room clip gives its middle PLATE_FRAMES (60: frames 5-64), read in chunks of 32: the
    statistics are computed once, at the end (each costs as much as adding tens of frames), and the model is the one
    of those frames fitted at once (as decoded one after the other)."""
    from silpose.app.recordings.silhouettes import PLATE_FRAMES
    from silpose.segment import BackgroundModel

    assert PLATE_FRAMES == 60  # the frames below
    (tmp_path / "empty").mkdir()
    size = (322, 242)  # the lab rig's aspect, read at its own size
    for k, cam in enumerate(rig):
        tools.write_video(tmp_path / "empty" / f"{cam.name}.mp4", background_frames(k, size, 70))
    finalised = []
    real = BackgroundModel._finalise
    monkeypatch.setattr(BackgroundModel, "_finalise", lambda self: (finalised.append(self.n_frames_seen_), real(self)))
    models = background_from_clips(tmp_path / "empty", rig, list(rig.names), {}, {c: size for c in rig.names}).models
    assert finalised == [60] * len(rig.names)
    for cam in rig:
        decoded = _decoded(tmp_path / "empty" / f"{cam.name}.mp4", 5, 60)
        np.testing.assert_allclose(models[cam.name].colour_mean_, decoded.mean(axis=0), rtol=1e-12)
        np.testing.assert_allclose(models[cam.name].colour_std_, decoded.std(axis=0), rtol=1e-12)


def test_a_long_plate_leaves_out_whoever_started_and_stopped_the_camera(rig, tools, tmp_path):
    """A 130-frame clip whose first and last 30 frames show someone (the operator walking out of the picture and
    back to stop the camera): the background is learnt from the 60 frames around its middle, sought to (not decoded
    up to), so the operator's pixels hold the room, not a mix of the room and the operator; the statistics are those
    of frames 35-94 decoded one after the other."""
    (tmp_path / "empty").mkdir()
    size = (322, 242)
    for k, cam in enumerate(rig):
        frames = background_frames(k, size, 130)
        frames[:30, 60:200, 20:80] = (40, 200, 40)  # the operator, beside the room's props
        frames[100:, 60:200, 240:300] = (40, 200, 40)
        tools.write_video(tmp_path / "empty" / f"{cam.name}.mp4", frames)
    models = background_from_clips(tmp_path / "empty", rig, list(rig.names), {}, {c: size for c in rig.names}).models
    for k, cam in enumerate(rig):
        clean = room(k, size).astype(np.float64)
        mean = models[cam.name].colour_mean_
        for box in (np.s_[60:200, 20:80], np.s_[60:200, 240:300]):
            assert np.abs(mean[box] - clean[box]).mean() < 4.0  # the room, within the noise and the codec
        decoded = _decoded(tmp_path / "empty" / f"{cam.name}.mp4", 35, 60)
        np.testing.assert_allclose(mean, decoded.mean(axis=0), rtol=1e-12)
        np.testing.assert_allclose(models[cam.name].colour_std_, decoded.std(axis=0), rtol=1e-12)


def test_a_cut_plate_whose_middle_is_gone_is_learnt_from_its_first_frames(rig, tmp_path):
    """An empty-room clip cut to a third of its bytes (MJPG: the frames before the cut still decode, the header still
    announces them all): its middle is not there, so its background is learnt from the frames that are, from the
    first -- not refused for having fewer than 2 frames after the seek -- and the run says so."""
    (tmp_path / "empty").mkdir()
    size = (322, 242)
    decodable = {}
    for k, cam in enumerate(rig):
        path = tmp_path / "empty" / f"{cam.name}.avi"
        w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, size)
        for f in background_frames(k, size, 200):
            w.write(f)
        w.release()
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 3])
        cap = cv2.VideoCapture(str(path))
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 200  # the header still says 200
        n = 0
        while cap.read()[0]:
            n += 1
        decodable[cam.name] = n
    assert all(2 <= n < 70 for n in decodable.values()), decodable  # the middle 60 (frames 70-129) are gone
    segmenter = background_from_clips(tmp_path / "empty", rig, list(rig.names), {}, {c: size for c in rig.names})
    for k, cam in enumerate(rig):
        assert segmenter.models[cam.name].n_frames_seen_ == min(decodable[cam.name], 60)
        assert np.abs(segmenter.models[cam.name].colour_mean_ - room(k, size)).mean() < 4.0
    # the user is told, one line per camera, in the rig's order
    assert len(segmenter.warnings) == len(rig.names)
    for cam, line in zip(rig, segmenter.warnings):
        assert line.startswith(str(tmp_path / "empty" / f"{cam.name}.avi"))
        assert "of the 200 its header announced" in line and f"its first {min(decodable[cam.name], 60)} frames" in line


def test_a_run_reports_a_cut_background_clip(tiny_model, tools, tmp_path):
    """``silpose infer --videos``: the line about a background clip cut short reaches the run's warnings (and so
    the terminal and summary.json)."""
    videos, empty = _nudged_room(tiny_model.rig_, tools, tmp_path, n=4)
    clip = empty / "cam1.mp4"
    size = (322, 242)
    clip.unlink()
    w = cv2.VideoWriter(str(empty / "cam1.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, size)
    for f in background_frames(1, size, 200):
        w.write(f)
    w.release()
    cut = empty / "cam1.avi"
    cut.write_bytes(cut.read_bytes()[: cut.stat().st_size // 3])
    s = run_recording(tiny_model, videos, tmp_path / "out", RecordingOptions(background=empty, overlays=False))
    lines = [w for w in s.warnings if "empty-room clip stops decoding" in w]
    assert len(lines) == 1 and lines[0].startswith(str(cut)) and "camera 'cam1'" in lines[0]
