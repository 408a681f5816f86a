"""The overlays' worker process (:class:`.overlay_video.OverlayWorker`, module docstring "Processes").

Run as ``python -m silpose.app.recordings.overlay_worker FOLDER SPEC``, SPEC being JSON:

- ``{"kind": "mp4", "sizes": {camera: [width, height]}, "fps": float, "fourcc": str}``: the worker opens
  ``FOLDER/<camera>.mp4`` for each camera and encodes each frame into its camera's video;
- ``{"kind": "png", "cameras": [camera, ...]}``: once every camera has given a frame, the worker tiles them in that
  order (:func:`.overlay_png.tile`) into ``FOLDER/<name>.png``, the name the messages carry, written atomically.

It reads messages (:mod:`.overlay_messages`) from its standard input, drawing each frame
(:func:`.overlay_video.draw_frame`), until the message of length 0; then it closes the videos and exits 0. Any error
(a video OpenCV cannot open, a malformed message, a drawing that fails) is one line on standard error and exit status
1; the parent reports it.
"""

from __future__ import annotations

import json
import signal
import sys
from pathlib import Path

import cv2

from silpose.shared.atomic import write_bytes_atomic

from .overlay_messages import read_message
from .overlay_png import tile
from .overlay_video import draw_frame

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """The worker (module docstring). Returns the exit status."""
    argv = sys.argv[1:] if argv is None else argv
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the run's: it ends the worker (docs/conventions.md)
    writers: dict = {}
    try:
        folder, spec = Path(argv[0]), json.loads(argv[1])
        cv2.setNumThreads(1)  # as in the run (.pipeline): the encoder's output does not depend on the machine
        if spec.get("kind", "mp4") == "png":
            _tile_pngs(folder, list(spec["cameras"]), sys.stdin.buffer)
            return 0
        fourcc = cv2.VideoWriter_fourcc(*spec["fourcc"])
        for camera, (w, h) in spec["sizes"].items():
            path = folder / f"{camera}.mp4"
            writers[camera] = cv2.VideoWriter(str(path), fourcc, float(spec["fps"]), (int(w), int(h)))
            if not writers[camera].isOpened():
                raise OSError(f"{path}: OpenCV cannot write {spec['fourcc']} video")
        stream = sys.stdin.buffer
        while (msg := read_message(stream, writers)) is not None:
            camera, what, _ = msg
            writers[camera].write(draw_frame(*what) if isinstance(what, tuple) else what)
    except Exception as exc:  # noqa: BLE001 - reported to the parent as one line
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        return 1
    finally:
        for w in writers.values():
            w.release()
    return 0


def _tile_pngs(folder: Path, cameras: list[str], stream) -> None:
    """PNG overlays (module docstring): each step's frames, one per camera, tiled into the file its messages name."""
    pending: dict[str, list] = {c: [] for c in cameras}
    while (msg := read_message(stream, pending)) is not None:
        camera, what, name = msg
        if name is None:
            raise ValueError(f"overlay message: camera {camera!r}'s frame names no PNG file")
        pending[camera].append((draw_frame(*what) if isinstance(what, tuple) else what, name))
        if all(pending.values()):
            step = [pending[c].pop(0) for c in cameras]
            ok, png = cv2.imencode(".png", tile([img for img, _ in step]))
            if not ok:
                raise OSError(f"{folder}: OpenCV cannot encode a PNG")
            write_bytes_atomic(folder / f"{step[0][1]}.png", png.tobytes())


if __name__ == "__main__":
    raise SystemExit(main())
