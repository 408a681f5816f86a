"""The overlay videos' worker process (:class:`.overlay_video.OverlayVideos`, module docstring "Processes").

Run as ``python -m silpose.app.recordings.overlay_worker FOLDER SPEC``: SPEC is JSON ``{"sizes": {camera: [width,
height]}, "fps": float, "fourcc": str}``. The worker opens ``FOLDER/<camera>.mp4`` for each camera, then reads
messages (:mod:`.overlay_messages`) from its standard input, drawing (:func:`.overlay_video.draw_frame`) and encoding
each frame, until the message of length 0; then it closes the videos and exits 0. Any error (a video OpenCV cannot
open, a malformed message, a drawing that fails) is one line on standard error and exit status 1; the parent reports
it.
"""

from __future__ import annotations

import json
import signal
import sys
from pathlib import Path

import cv2

from .overlay_messages import read_message
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
        fourcc = cv2.VideoWriter_fourcc(*spec["fourcc"])
        for camera, (w, h) in spec["sizes"].items():
            path = folder / f"{camera}.mp4"
            writers[camera] = cv2.VideoWriter(str(path), fourcc, float(spec["fps"]), (int(w), int(h)))
            if not writers[camera].isOpened():
                raise OSError(f"{path}: OpenCV cannot write {spec['fourcc']} video")
        stream = sys.stdin.buffer
        while (msg := read_message(stream, writers)) is not None:
            camera, what = msg
            writers[camera].write(draw_frame(*what) if isinstance(what, tuple) else what)
    except Exception as exc:  # noqa: BLE001 - reported to the parent as one line
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        return 1
    finally:
        for w in writers.values():
            w.release()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
