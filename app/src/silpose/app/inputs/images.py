"""The file suffixes every camera input reads as frames or as videos, the order of a folder's frames, a video's display
rotation, and how errors print a frame size.

Frames and videos are read by :mod:`silpose.app.recordings.sources` (one reader for every camera input).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
"""Image file suffixes read as frames (case-insensitive): the one list every camera input uses."""
VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm")
"""Video file suffixes read as a camera (case-insensitive; OpenCV's FFmpeg decodes them): the one list every
camera input uses (frames folders, recordings, ``silpose rig import``'s image-size probe)."""


def frame_order(path: Path | str) -> tuple:
    """Sort key of a frame file in its folder: the name's runs of digits compared as numbers (``img2.png`` before
    ``img10.png``, as exporters that do not zero-pad name frames), then the name itself; zero-padded names keep
    their order."""
    name = Path(path).name
    parts = re.split(r"(\d+)", name.lower())
    return tuple((0, int(t), "") if t.isdigit() else (1, 0, t) for t in parts), name


def frame_size_text(shape) -> str:
    """``"<W>x<H> (WxH)"`` for an image shape (H, W[, C]), as error messages print frame sizes."""
    return f"{shape[1]}x{shape[0]} (WxH)"


def display_rotation(cap) -> int:
    """Degrees (0, 90, 180 or 270) by which an opened ``cv2.VideoCapture``'s metadata (the display matrix a phone
    writes for a portrait video) asks players to rotate its frames: OpenCV's ``CAP_PROP_ORIENTATION_META``, 0 when
    absent or not a multiple of 90."""
    import cv2

    value = float(cap.get(cv2.CAP_PROP_ORIENTATION_META) or 0.0)
    if not math.isfinite(value) or round(value) % 90:
        return 0
    return int(round(value)) % 360
