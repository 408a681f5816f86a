"""OverlayVideos: each camera's frames in order in its own video, whatever threads or worker processes serve the
cameras (the same bytes either way); errors and aborts leave nothing behind."""

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
    videos = OverlayVideos(tmp_path, cams, {c: (64, 48) for c in cams}, 25.0, processes=False)
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
    videos = OverlayVideos(tmp_path, ["a", "b"], {"a": (64, 48), "b": (64, 48)}, 25.0, processes=False)
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
        OverlayVideos(tmp_path, cams, {c: (64, 48) for c in cams}, 25.0, processes=False)
    assert len(released) == 2  # the two writers opened before it
    assert not any(tmp_path.iterdir())  # no working folder, no overlays folder


def _people(rng, k: int) -> list[dict]:
    """Drawing items of two people, as the pipeline lists them: outlines, reconstructions, joints, a missing view."""
    ring = np.stack([np.cos(np.linspace(0, 2 * np.pi, 40)), np.sin(np.linspace(0, 2 * np.pi, 40))], 1)
    return [{"person": 1, "status": "ok", "outline": 20 + 8 * ring + rng.normal(0, 0.5, (40, 2)),
             "recon": 20 + 7 * ring, "joints_px": rng.uniform(5, 40, (19, 2)), "anchor_px": np.array([20.0, 5.0])},
            {"person": 2 + k % 2, "status": "merged", "outline": None, "recon": 40 + 6 * ring, "joints_px": None,
             "anchor_px": np.array([44.0, 9.0])}]


def _write_all(videos, cams, rng) -> list:
    mask = (rng.random((48, 64)) < 0.3).astype(np.uint8)
    colour = rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)
    for k in range(6):
        for i, c in enumerate(cams):
            if k == 3:
                videos.write(c, _frame(i, k))
            else:
                videos.draw(c, mask if k % 2 else (colour if k == 2 else None), (64, 48), k, _people(rng, k))
    return videos.close()


@pytest.mark.parametrize("cores", [2, 3])
def test_worker_processes_write_the_same_videos_as_threads(tmp_path, monkeypatch, cores):
    """The frames drawn and encoded in worker processes (their arguments sent down a pipe) are the frames the
    in-process threads make: the same files, byte for byte."""
    import hashlib

    monkeypatch.setattr(overlay_video.os, "cpu_count", lambda: cores)
    cams = ["cam0", "cam1", "cam2"]
    got = {}
    for processes in (False, True):
        videos = OverlayVideos(tmp_path / str(processes), cams, {c: (64, 48) for c in cams}, 25.0, processes=processes)
        assert len(videos.encoders) == cores - 1
        paths = _write_all(videos, cams, np.random.default_rng(0))
        got[processes] = [hashlib.md5(p.read_bytes()).hexdigest() for p in paths]
        assert len(_levels(paths[0])) == 6
        assert not list((tmp_path / str(processes)).glob(".overlays.*"))
    assert got[True] == got[False]


def test_a_worker_that_dies_is_raised_and_abort_drops_everything(tmp_path):
    videos = OverlayVideos(tmp_path, ["a", "b"], {"a": (64, 48), "b": (64, 48)}, 25.0, processes=True)
    videos.write("a", _frame(0, 0))
    videos.encoders[0].proc.kill()
    with pytest.raises(OSError, match="overlay videos of a, b failed"):
        for _ in range(200):  # raised by a later write (or by close)
            videos.write("a", _frame(0, 1))
        videos.close()
    videos.abort()
    assert not any(tmp_path.iterdir())


def test_a_worker_that_cannot_open_a_video_says_so(tmp_path):
    """OpenCV refuses a 0 x 0 video: the worker's one line reaches the caller."""
    videos = OverlayVideos(tmp_path, ["a"], {"a": (0, 0)}, 25.0, processes=True)
    with pytest.raises(OSError, match=r"a\.mp4: OpenCV cannot write"):
        for _ in range(50):
            videos.write("a", _frame(0, 0))
        videos.close()
    videos.abort()
    assert not any(tmp_path.iterdir())


def test_a_worker_imports_silpose_from_where_the_run_found_it(monkeypatch, tmp_path):
    """A script that put a source checkout on sys.path starts workers that import the same silpose."""
    monkeypatch.setattr(overlay_video.sys, "path", [str(tmp_path / "checkout"), "", *overlay_video.sys.path])
    monkeypatch.setenv("PYTHONPATH", str(tmp_path / "user"))
    paths = overlay_video.worker_env()["PYTHONPATH"].split(overlay_video.os.pathsep)
    assert paths[0] == str(tmp_path / "checkout") and "" not in paths
    assert paths[-1] == str(tmp_path / "user") and len(paths) == len(set(paths))
    monkeypatch.setattr(overlay_video.sys, "executable", "")
    assert not overlay_video.overlay_processes()  # no executable to start: threads


@pytest.mark.parametrize("names", [None, ["a_01", "a_02", "b_07", "b_08", "c", "d"]])
def test_png_overlays_from_a_worker_process_are_the_threads_files(tmp_path, names):
    """PNG overlays drawn, tiled and encoded in a worker process: the files (names and bytes) the run's thread
    writes, a frames folder's names included."""
    from silpose.app.recordings.overlay_png import OverlayPngs

    cams = ["cam0", "cam1", "cam2"]
    got = {}
    for processes in (False, True):
        empty = OverlayPngs(tmp_path / str(processes), cams, first_frame=40, frame_names=names, processes=processes)
        assert empty.close() == []  # nothing written: no folder to report
        pngs = OverlayPngs(tmp_path / str(processes), cams, first_frame=40, frame_names=names, processes=processes)
        assert _write_all(pngs, cams, np.random.default_rng(1)) == [tmp_path / str(processes)]
        got[processes] = {p.name: p.read_bytes() for p in sorted((tmp_path / str(processes)).iterdir())}
    assert list(got[True]) == [f"{n}.png" for n in (names or [f"{40 + i:05d}" for i in range(6)])]
    assert got[True] == got[False]
    assert cv2.imdecode(np.frombuffer(got[True][next(iter(got[True]))], np.uint8), cv2.IMREAD_COLOR).shape == (96, 128, 3)


def test_a_png_worker_that_dies_is_raised(tmp_path):
    from silpose.app.recordings.overlay_png import OverlayPngs

    pngs = OverlayPngs(tmp_path / "png", ["a"], processes=True)
    pngs.write("a", _frame(0, 0))
    pngs.worker.proc.kill()
    with pytest.raises(OSError, match="PNG overlays of a failed"):
        for _ in range(200):
            pngs.write("a", _frame(0, 1))
        pngs.close()
    pngs.abort()


def test_a_worker_starts_one_blas_thread(tmp_path):
    """The workers multiply no matrices: numpy in a worker's environment reports one BLAS thread (threadpoolctl),
    whatever the machine's cores."""
    import subprocess
    import sys

    code = ("import numpy, threadpoolctl; "
            "print(max(i['num_threads'] for i in threadpoolctl.threadpool_info() if i['user_api'] == 'blas'))")
    out = subprocess.run([sys.executable, "-c", code], env=overlay_video.worker_env(), capture_output=True, text=True,
                         check=True, cwd=tmp_path)
    assert out.stdout.strip() == "1"
