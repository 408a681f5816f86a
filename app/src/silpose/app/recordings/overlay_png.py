"""Overlays as one PNG per frame, and the choice between them and the overlay videos (``--overlays png|mp4|none``).

``png``: ``<folder>/<frame>.png``, every camera's overlay frame (:func:`.overlay_video.draw_frame`, the picture
the videos show) tiled in rig order, ``ceil(sqrt(K))`` tiles a row, each at its camera's working size; lossless,
one file per time step (``<frame>`` is the frames folder's file name, else the frame index ``00042``). Each file is
written atomically (:mod:`silpose.shared.atomic`). On 2 cores or more the frames are drawn, tiled and encoded in a
worker process, as the videos are (:mod:`.overlay_video`, "Processes"): the lab recording (4 x 644x486 mask videos,
150 steps, three alternating pairs) made 44.8 / 36.6 / 42.1 time steps/s against 31.1 / 32.5 / 36.1 with the PNGs
encoded in the run's thread (~9 ms a 1288x972 PNG), the same files. ``mp4``: :class:`.overlay_video.OverlayVideos`, one video per
camera in the folder.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from silpose.shared.atomic import write_bytes_atomic

from .overlay_video import OverlayVideos, OverlayWorker, draw_frame, overlay_processes

#: the values of ``--overlays``
OVERLAY_FORMATS = ("png", "mp4", "none")


def overlay_format(value) -> str:
    """``"png"``, ``"mp4"`` or ``"none"`` from an option value (True: ``"mp4"``, False / None: ``"none"``)."""
    if value is True:
        return "mp4"
    if value is False or value is None:
        return "none"
    value = str(value).lower()
    if value not in OVERLAY_FORMATS:
        raise ValueError(f"--overlays: {value!r} is not one of {', '.join(OVERLAY_FORMATS)}")
    return value


def draws_overlays(value) -> bool:
    """True when the option value asks for overlays."""
    return overlay_format(value) != "none"


def tile(images: list[np.ndarray]) -> np.ndarray:
    """(H, W, 3) uint8: ``images`` (each (h, w, 3) uint8) in a grid of ``ceil(sqrt(K))`` columns, black padding."""
    cols = math.ceil(math.sqrt(len(images)))
    rows = math.ceil(len(images) / cols)
    h = max(im.shape[0] for im in images)
    w = max(im.shape[1] for im in images)
    out = np.zeros((rows * h, cols * w, 3), np.uint8)
    for i, im in enumerate(images):
        r, c = divmod(i, cols)
        out[r * h : r * h + im.shape[0], c * w : c * w + im.shape[1]] = im
    return out


class OverlayPngs:
    """Same ``write(camera, image)`` / ``draw(...)`` / ``close()`` / ``abort()`` as
    :class:`~.overlay_video.OverlayVideos`: a step's PNG is written once every camera has given its frame (module
    docstring). With ``processes`` (None: :func:`~.overlay_video.overlay_processes`) the frames are drawn, tiled and
    encoded in a worker process (:class:`~.overlay_video.OverlayWorker`; each message names its step's file), else
    in the run's thread; the same files either way."""

    def __init__(self, folder: Path, cameras, first_frame: int = 0, frame_names: list[str] | None = None,
                 processes: bool | None = None):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.cameras = list(cameras)
        self.first_frame, self.frame_names = int(first_frame), frame_names
        self.pending: dict[str, list[np.ndarray]] = {c: [] for c in self.cameras}
        self.files: list[Path] = []
        self.sent = dict.fromkeys(self.cameras, 0)  # frames handed to the worker, per camera
        self.worker = (OverlayWorker(self.folder, {"kind": "png", "cameras": self.cameras}, self.cameras,
                                     "PNG overlays")
                       if (overlay_processes() if processes is None else processes) else None)

    def _name(self, i: int) -> str:
        if self.frame_names is not None and i < len(self.frame_names):
            return str(self.frame_names[i])
        return f"{self.first_frame + i:05d}"

    def _send(self, camera: str, what) -> None:
        self.worker.write(camera, what, self._name(self.sent[camera]))
        self.sent[camera] += 1

    def write(self, camera: str, image: np.ndarray) -> None:
        if self.worker is not None:
            self._send(camera, image)
            return
        self.pending[camera].append(image)
        if all(self.pending[c] for c in self.cameras):
            ok, png = cv2.imencode(".png", tile([self.pending[c].pop(0) for c in self.cameras]))
            if not ok:
                raise OSError(f"{self.folder}: OpenCV cannot encode a PNG")
            self.files.append(write_bytes_atomic(self.folder / f"{self._name(len(self.files))}.png", png.tobytes()))

    def draw(self, camera: str, background: np.ndarray | None, size: tuple[int, int], frame: int,
             people: list[dict]) -> None:
        """Draw (:func:`.overlay_video.draw_frame`) and write one camera's frame (as ``OverlayVideos.draw``;
        ``background`` must not change afterwards)."""
        if self.worker is not None:
            self._send(camera, (background, size, camera, frame, people))
            return
        self.write(camera, draw_frame(background, size, camera, frame, people))

    def close(self) -> list[Path]:
        if self.worker is not None:
            self.worker.finish()
            return [self.folder] if min(self.sent.values(), default=0) > 0 else []
        return [self.folder] if self.files else []

    def abort(self) -> None:  # every file written is whole (atomic); nothing to drop
        if self.worker is not None:
            self.worker.kill()


def overlay_sink(value, folder: Path, cameras, sizes: dict, fps: float, first_frame: int = 0,
                 frame_names: list[str] | None = None):
    """The overlay writer ``value`` asks for (:func:`overlay_format`) into ``folder``, or None.

    sizes: {camera: (width, height)} of the drawn frames; fps: the videos' rate (0: 25)."""
    kind = overlay_format(value)
    if kind == "png":
        return OverlayPngs(folder, cameras, first_frame, frame_names)
    if kind == "mp4":
        videos = OverlayVideos(Path(folder).parent, cameras, sizes, fps)
        videos.final = Path(folder)  # moved there by close(); the working copy is a hidden sibling
        return videos
    return None
