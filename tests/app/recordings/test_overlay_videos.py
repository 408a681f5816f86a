"""OverlayVideos: each camera's frames in order in its own video, whatever threads serve the cameras; errors and
aborts leave nothing behind."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.app.recordings import overlay_video
from silpose.app.recordings.overlay_video import OverlayVideos, overlay_threads


def _frame(cam: int, k: int, size=(64, 48)) -> np.ndarray:
    """A frame whose grey level encodes its camera and index (coarse steps: the codec is lossy)."""
    return np.full((size[1], size[0], 3), 20 + 40 * cam + 8 * k, np.uint8)


def _levels(path) -> list[float]:
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        out.append(float(img.mean()))
    cap.release()
    return out


@pytest.mark.parametrize("cores", [2, 3, 16])
def test_every_camera_gets_its_own_frames_in_order(tmp_path, monkeypatch, cores):
    monkeypatch.setattr(overlay_video.os, "cpu_count", lambda: cores)
    cams = [f"cam{i}" for i in range(4)]
    videos = OverlayVideos(tmp_path, cams, {c: (64, 48) for c in cams}, 25.0)
    assert len(videos.encoders) == overlay_threads(4) == min(4, cores - 1)
    for k in range(5):
        for i, c in enumerate(cams):  # images and drawn frames mixed, as the pipeline's callers do
            if k % 2:
                videos.write(c, _frame(i, k))
            else:
                videos.draw(c, None, (64, 48), k, [])
    paths = videos.close()
    assert [p.name for p in paths] == [f"{c}.mp4" for c in cams]
    assert not list(tmp_path.glob(".overlays.*"))  # the working folder is gone
    for i, p in enumerate(paths):
        got = _levels(p)
        assert len(got) == 5
        for k in (1, 3):  # the written images: this camera's, in order (drawn frames are near black)
            assert abs(got[k] - (20 + 40 * i + 8 * k)) < 3
        for k in (0, 2, 4):
            assert got[k] < 10


def test_a_failing_writer_is_raised_and_abort_drops_everything(tmp_path, monkeypatch):
    monkeypatch.setattr(overlay_video.os, "cpu_count", lambda: 2)  # one thread serves both cameras
    real = overlay_video.draw_frame

    def draw(background, size, camera, frame, people):
        if camera == "b":
            raise ValueError("cannot draw b")
        return real(background, size, camera, frame, people)

    monkeypatch.setattr(overlay_video, "draw_frame", draw)
    videos = OverlayVideos(tmp_path, ["a", "b"], {"a": (64, 48), "b": (64, 48)}, 25.0)
    videos.write("a", _frame(0, 0))
    videos.draw("b", None, (64, 48), 0, [])  # fails in the encoder thread
    with pytest.raises(ValueError, match="cannot draw b"):
        for _ in range(200):  # raised by a later write (or by close)
            videos.write("a", _frame(0, 1))
        videos.close()
    videos.abort()
    assert not list(tmp_path.glob(".overlays.*")) and not (tmp_path / "overlays").exists()


def test_overlay_threads_leave_a_core_to_the_run(monkeypatch):
    for cores, cams, want in ((1, 4, 1), (2, 4, 1), (3, 4, 2), (8, 4, 4), (8, 1, 1)):
        monkeypatch.setattr(overlay_video.os, "cpu_count", lambda c=cores: c)
        assert overlay_threads(cams) == want


def test_a_camera_whose_video_cannot_be_opened_leaves_nothing(tmp_path, monkeypatch):
    real = overlay_video.cv2.VideoWriter
    released = []

    class Writer:
        def __init__(self, path, *args):
            self.inner = real(path, *args) if "cam2" not in str(path) else None
            self.path = path

        def isOpened(self):
            return self.inner is not None

        def release(self):
            released.append(self.path)
            if self.inner is not None:
                self.inner.release()

    monkeypatch.setattr(overlay_video.cv2, "VideoWriter", Writer)
    cams = [f"cam{i}" for i in range(4)]
    with pytest.raises(OSError, match="cam2.mp4"):
        OverlayVideos(tmp_path, cams, {c: (64, 48) for c in cams}, 25.0)
    assert len(released) == 2  # the two writers opened before it
    assert not any(tmp_path.iterdir())  # no working folder, no overlays folder
