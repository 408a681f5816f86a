"""One overlay video per camera: what the recording saw and what silpose inferred, frame by frame.

``<out>/overlays/<camera>.mp4`` (MPEG-4 part 2, the recording's frame rate), the camera's image size.
Each frame shows, over the dimmed mask (or colour frame):

- every person's own silhouette (their blob, when the view was used), tinted and outlined in the person's
  colour;
- the model's reconstructed contour of that view, white (dashed grey where the view was missing:
  merged, cut by the border or not seen, projected from the inferred body, :mod:`.placement`);
- the inferred skeleton projected into the camera, in the person's colour;
- the person's id at the head (``?`` while a track is not yet a person), with the view's status when
  the view was not used; the frame number and camera name at the top left.

Processes: the frames are drawn and encoded beside the run, which only lists what each frame shows
(:meth:`OverlayVideos.draw`): on a machine with two cores or more (:func:`overlay_processes`) in worker processes
(:class:`OverlayWorker`, :mod:`.overlay_worker`; PNG overlays too, :mod:`.overlay_png`), each frame's arguments sent
down a pipe (:mod:`.overlay_messages`; a thread of the run's
process writes them), else in threads of the run's process. One worker (or thread) per camera, at most the CPU count
less one (:func:`overlay_threads`), each serving its cameras' frames in the order they come: on the 2-core machine
one for every camera. Both give the same videos byte for byte. Why processes: a thread drawing beside the run's
thread takes turns with it at the GIL (every OpenCV call releases it and waits to take it back), so the overlay thread
fell behind and the run waited for it. Measured on the lab recording played 3x (4 x 644x486 mask videos, 450 steps,
the idle 2-core machine, three alternating rounds): 72.4 / 68.5 / 72.4 time steps/s with the worker process against
53.8 / 58.4 / 62.4 with the thread, and 89.1 / 86.0 / 99.8 without overlays -- the overlays' share of the run 19-27 %
against 32-40 %. A worker starts in about 0.2 s (a fresh Python importing OpenCV and numpy, on the other core while
the run sets up). Four threads instead of one on this machine had cost more than they gave (five alternating pairs:
60.0 / 57.6 / 48.1 / 55.7 / 58.4 time steps/s with one thread against 48.7 / 41.3 / 46.8 / 50.4 / 48.8 with four).
``benchmarks/recordings.py`` reports the overlays' share against the same run without them, the workers' CPU
included.

The videos are written into a temporary folder ``<out>/.overlays.<pid>.tmp/`` and moved into
``<out>/overlays/`` when the run ends (OpenCV picks the container from the file suffix, so the
``.<name>.<pid>.tmp`` names of :mod:`silpose.shared.atomic` would not work).
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import cv2
import numpy as np

from silpose.shared.skeleton import BONES

from .overlay_messages import END, pack, pack_image
from .views import VIEW_OK

#: BGR colours of persons 1, 2, ... (cycled); tentative tracks are grey
PALETTE = ((60, 180, 255), (255, 140, 60), (90, 220, 90), (200, 90, 230), (60, 230, 230), (230, 200, 90))
GREY = (150, 150, 150)
FOURCC = "mp4v"
_BONE_INDEX = np.array(BONES, np.intp)  # (bones, 2): a skeleton's (19, 2) points -> its bones' (bones, 2, 2) ends


def person_colour(person: int) -> tuple[int, int, int]:
    return PALETTE[(person - 1) % len(PALETTE)] if person > 0 else GREY


def _poly(img, pts, colour, thickness=1, dashed=False) -> None:
    p = np.asarray(pts, float)
    if p.ndim != 2 or not np.all(np.isfinite(p)):
        return
    q = np.round(p * 16).astype(np.int32)
    if not dashed:
        cv2.polylines(img, [q], True, colour, thickness, cv2.LINE_AA, shift=4)
        return
    cv2.polylines(img, dashes(q), False, colour, thickness, cv2.LINE_AA, shift=4)  # one call: drawn in turn


def dashes(q: np.ndarray) -> list[np.ndarray]:
    """The dashes of a dashed outline of points ``q`` (n, 2): points 4i .. 4i + 2 (every other pair of segments),
    the last one when it has 2 points or more; views of ``q``, cut by one reshape (no Python loop over the points)."""
    whole = len(q) // 4
    out = list(q[: 4 * whole].reshape(whole, 4, 2)[:, :3])
    if len(q) - 4 * whole >= 2:
        out.append(q[4 * whole : 4 * whole + 3])
    return out


def _tint(img: np.ndarray, people: list[dict]) -> None:
    """Blend each person's filled outline into ``img`` (in place) at 40 %: only inside the outlines' box (the
    blend leaves every other pixel as it is)."""
    polys = [np.round(p["outline"]).astype(np.int32) for p in people
             if p.get("outline") is not None and np.all(np.isfinite(p["outline"]))]
    if not polys:
        return
    h, w = img.shape[:2]
    allp = np.concatenate(polys)
    x0, y0 = np.clip(allp.min(axis=0), 0, (w, h))
    x1, y1 = np.clip(allp.max(axis=0) + 1, 0, (w, h))
    if x1 <= x0 or y1 <= y0:
        return
    roi = img[y0:y1, x0:x1]
    tint = roi.copy()
    for p, poly in zip([p for p in people if p.get("outline") is not None and np.all(np.isfinite(p["outline"]))], polys):
        cv2.fillPoly(tint, [poly - (x0, y0)], person_colour(p["person"]))
    cv2.addWeighted(roi, 0.6, tint, 0.4, 0.0, dst=roi)


def draw_frame(background: np.ndarray | None, size: tuple[int, int], camera: str, frame: int, people: list[dict]) -> np.ndarray:
    """One overlay frame (H, W, 3) uint8 BGR.

    background: (H, W) {0, 1} mask or (H, W, 3) BGR frame, or None (black, ``size`` = (W, H)). people: one dict per person seen
    in this step: ``person`` (id, 0 = tentative), ``status`` (this view's), ``outline`` ((n, 2) px or None),
    ``recon`` ((n, 2) px or None), ``joints_px`` ((19, 2) px or None), ``anchor_px`` ((2,) px: where the
    label goes when there are no joints, e.g. the projected top of the person's column).
    """
    if background is None:
        img = np.zeros((size[1], size[0], 3), np.uint8)
    elif background.ndim == 2:
        img = cv2.cvtColor(background * np.uint8(70), cv2.COLOR_GRAY2BGR)  # uint8 * uint8: uint8
    else:
        img = cv2.convertScaleAbs(background, alpha=0.6)  # dimmed (rounded; OpenCV, not a float64 copy)
    _tint(img, people)
    placed: list[tuple[int, int]] = []
    for p in people:
        col = person_colour(p["person"])
        ok = p["status"] == VIEW_OK
        if p.get("outline") is not None:
            _poly(img, p["outline"], col, 1)
        if p.get("recon") is not None:
            _poly(img, p["recon"], (255, 255, 255) if ok else (170, 170, 170), 1, dashed=not ok)
        j = p.get("joints_px")
        if j is not None and np.all(np.isfinite(j)):
            q = np.round(j * 16).astype(np.int32)
            cv2.polylines(img, list(q[_BONE_INDEX]), False, col, 2, cv2.LINE_AA, shift=4)  # one call
            top = j[:, 1].argmin()
            anchor = (int(j[top, 0]) - 10, max(int(j[top, 1]) - 12, 14))
        elif p.get("anchor_px") is not None and np.all(np.isfinite(p["anchor_px"])):
            anchor = (int(p["anchor_px"][0]) - 10, max(int(p["anchor_px"][1]), 14))
        else:
            continue
        label = f"#{p['person']}" if p["person"] > 0 else "?"
        if not ok:
            label += f" {p['status']}"
        while any(abs(anchor[0] - a) < 90 and abs(anchor[1] - b) < 14 for a, b in placed):  # labels must not overlap
            anchor = (anchor[0], anchor[1] - 15)
        placed.append(anchor)
        cv2.putText(img, label, anchor, cv2.FONT_HERSHEY_SIMPLEX, 0.5, col, 1, cv2.LINE_AA)
    cv2.putText(img, f"{camera}  frame {frame}", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (230, 230, 230), 1, cv2.LINE_AA)
    return img


def overlay_threads(n_cameras: int) -> int:
    """Drawing-and-encoding threads for ``n_cameras`` overlay videos: one per camera, at most the CPU count less one
    (the run's thread keeps a core; module docstring, "Threads"), at least one."""
    return max(1, min(int(n_cameras), (os.cpu_count() or 1) - 1))


def overlay_processes() -> bool:
    """Whether the overlay videos are drawn and encoded in worker processes (module docstring, "Processes"): on
    every machine with two cores or more, when this Python knows its own executable."""
    return (os.cpu_count() or 1) >= 2 and bool(sys.executable)


#: a worker draws, encodes and plots; it multiplies no matrices, so its BLAS starts one thread, not one per core:
#: numpy's import then costs the worker about half the CPU time (``import cv2``: 0.24 -> 0.13 CPU s on the 2-core
#: machine, OpenBLAS no longer setting up a second thread's buffers) -- on a 150-step run ~0.7 ms of CPU a step
ONE_BLAS_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def worker_env() -> dict:
    """The environment of a worker process: this one's, with this process's ``sys.path`` ahead of ``PYTHONPATH``,
    so that the worker imports the same silpose however this process found it (an installed package, a source
    checkout on ``PYTHONPATH``, a path a script added); and one BLAS thread (:data:`ONE_BLAS_THREAD`)."""
    env = dict(os.environ)
    paths = [p for p in sys.path if p] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    env["PYTHONPATH"] = os.pathsep.join(dict.fromkeys(paths))
    env.update(ONE_BLAS_THREAD)
    return env


class _Encoder:
    """The video writers of some cameras, drawing and encoding in one thread of their own (OpenCV's drawing and
    encoder release the GIL): the run's thread only lists what to draw. A queued item is ``(camera, image)`` or
    ``(camera, the arguments of`` :func:`draw_frame` ``as a tuple)``, drawn and written in the order queued (each
    camera's frames in order). ``depth`` items per camera are queued at most."""

    def __init__(self, writers: dict, depth: int = 24):
        self.writers = writers
        self.queue: queue.Queue = queue.Queue(maxsize=depth * max(1, len(writers)))
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="overlay-encoder", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while True:
            item = self.queue.get()
            if item is None:
                return
            if self.error is None:
                camera, img = item
                try:
                    self.writers[camera].write(draw_frame(*img) if isinstance(img, tuple) else img)
                except BaseException as exc:  # raised by the next write or by finish
                    self.error = exc

    def write(self, camera: str, img) -> None:
        if self.error is not None:
            raise self.error
        self.queue.put((camera, img))

    def finish(self) -> None:
        self.queue.put(None)
        self.thread.join()
        for w in self.writers.values():
            w.release()
        if self.error is not None:
            raise self.error


class OverlayWorker:
    """The overlays of some cameras drawn in a worker process of its own (module docstring, "Processes";
    :mod:`.overlay_worker`, whose SPEC is ``spec``), with :class:`_Encoder`'s ``write`` / ``finish``: the run's thread
    queues each frame's message (:func:`~.overlay_messages.pack`), a thread of this process writes it into the
    worker's pipe (the GIL released while the pipe takes it), ``depth`` messages per camera at most. The worker's
    error line, if any, is raised as OSError (``what`` of ``cameras`` failed) by the next ``write`` or by ``finish``;
    its standard error goes to a temporary file, off the terminal."""

    def __init__(self, folder: Path, spec: dict, cameras: list[str], what: str = "overlay videos", depth: int = 24):
        self.cameras, self.what = list(cameras), what
        fd, log = tempfile.mkstemp(prefix="silpose-overlays-", suffix=".log")
        self.log_path = Path(log)
        try:
            with os.fdopen(fd, "wb") as stderr:
                self.proc = subprocess.Popen([sys.executable, "-m", "silpose.app.recordings.overlay_worker",
                                              str(folder), json.dumps(spec)], stdin=subprocess.PIPE,
                                             stdout=subprocess.DEVNULL, stderr=stderr, env=worker_env())
        except BaseException:
            self.log_path.unlink(missing_ok=True)
            raise
        self.queue: queue.Queue = queue.Queue(maxsize=depth * max(1, len(self.cameras)))
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="overlay-pipe", daemon=True)
        self.thread.start()

    def _failure(self) -> OSError:
        try:
            self.proc.wait(timeout=10)
            line = self.log_path.read_text(errors="replace").strip().splitlines()[-1:]
        except (OSError, subprocess.TimeoutExpired):
            line = []
        why = line[0] if line else f"exit status {self.proc.returncode}"
        return OSError(f"the {self.what} of {', '.join(self.cameras)} failed: {why}")

    def _run(self) -> None:
        pipe = self.proc.stdin
        while True:
            msg = self.queue.get()
            if msg is None:
                return
            if self.error is None:
                try:
                    for part in msg:
                        pipe.write(part if isinstance(part, bytes) else memoryview(part).cast("B"))
                except (BrokenPipeError, OSError, ValueError):
                    self.error = self._failure()

    def write(self, camera: str, img, name: str | None = None) -> None:
        """Queue ``img`` (an image, or :func:`draw_frame`'s arguments) of ``camera``; ``name``: its PNG file."""
        if self.error is not None:
            raise self.error
        if isinstance(img, tuple):  # draw_frame's arguments: (background, size, camera, frame, people)
            background, size, _, frame, people = img
            self.queue.put(pack(camera, background, size, frame, people, name))
        else:
            self.queue.put(pack_image(camera, img, name))

    def finish(self) -> None:
        self.queue.put([END])
        self.queue.put(None)
        self.thread.join()
        try:
            self.proc.stdin.close()  # the worker's end of the stream (its buffered last bytes are written)
        except (OSError, ValueError):  # a worker that died: the error below says why
            pass
        if self.error is None and self.proc.wait() != 0:
            self.error = self._failure()
        self.log_path.unlink(missing_ok=True)
        if self.error is not None:
            raise self.error

    def kill(self) -> None:
        """Stop the worker now (an abort: its videos are dropped) and the thread feeding it."""
        self.proc.kill()
        self.proc.wait()
        while True:  # what was still queued is dropped; the thread sees the end
            try:
                self.queue.get_nowait()
            except queue.Empty:
                break
        self.queue.put(None)
        self.thread.join()
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        self.log_path.unlink(missing_ok=True)


class OverlayVideos:
    """Writers of the per-camera overlay videos (module docstring). ``write(camera, image)`` or ``draw(camera,
    ...)`` per frame (drawn and encoded in the camera's thread, :func:`overlay_threads`), ``close()`` moves the
    finished videos into ``<out>/overlays/``, ``abort()`` drops them."""

    def __init__(self, out: Path, cameras, sizes: dict, fps: float, processes: bool | None = None):
        self.final = Path(out) / "overlays"
        self.tmp = Path(out) / f".overlays.{os.getpid()}.tmp"
        shutil.rmtree(self.tmp, ignore_errors=True)
        self.tmp.mkdir(parents=True)
        self.cameras = list(cameras)
        self.encoders: list[_Encoder | OverlayWorker] = []
        self.encoder_of: dict[str, _Encoder | OverlayWorker] = {}
        fps = fps if fps > 0 else 25.0
        n = overlay_threads(len(self.cameras))
        groups = [self.cameras[g::n] for g in range(n)]  # cameras dealt round the threads or processes
        if overlay_processes() if processes is None else processes:
            try:
                for group in groups:
                    spec = {"kind": "mp4", "sizes": {c: list(map(int, sizes[c])) for c in group}, "fps": float(fps),
                            "fourcc": FOURCC}
                    enc = OverlayWorker(self.tmp, spec, group)
                    self.encoders.append(enc)
                    self.encoder_of.update(dict.fromkeys(group, enc))
            except BaseException:
                self.abort()
                raise
            self.n_frames = 0
            return
        writers = {}
        try:
            for cam in self.cameras:
                path = self.tmp / f"{cam}.mp4"
                w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*FOURCC), fps, sizes[cam])
                if not w.isOpened():
                    raise OSError(f"{path}: OpenCV cannot write {FOURCC} video")
                writers[cam] = w
        except BaseException:
            for w in writers.values():
                w.release()
            shutil.rmtree(self.tmp, ignore_errors=True)
            raise
        for group in groups:
            enc = _Encoder({c: writers[c] for c in group})
            self.encoders.append(enc)
            self.encoder_of.update(dict.fromkeys(group, enc))
        self.n_frames = 0

    def write(self, camera: str, image: np.ndarray) -> None:
        self.encoder_of[camera].write(camera, image)

    def draw(self, camera: str, background: np.ndarray | None, size: tuple[int, int], frame: int,
             people: list[dict]) -> None:
        """Queue the frame :func:`draw_frame` ``(background, size, camera, frame, people)`` draws: it is drawn and
        encoded in the camera's thread (``background`` must not change afterwards)."""
        self.encoder_of[camera].write(camera, (background, size, camera, frame, people))

    def close(self) -> list[Path]:
        for enc in self.encoders:
            enc.finish()
        self.final.mkdir(parents=True, exist_ok=True)
        out = []
        for cam in self.cameras:
            dst = self.final / f"{cam}.mp4"
            os.replace(self.tmp / f"{cam}.mp4", dst)
            out.append(dst)
        shutil.rmtree(self.tmp, ignore_errors=True)
        return out

    def abort(self) -> None:
        for enc in self.encoders:
            try:
                enc.kill() if isinstance(enc, OverlayWorker) else enc.finish()
            except BaseException:  # noqa: BLE001 - aborting: the files are dropped anyway
                pass
        shutil.rmtree(self.tmp, ignore_errors=True)
