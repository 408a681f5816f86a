"""Frame loaders: a folder of images, or a video file (OpenCV).

Both return BGR uint8 stacks, ready for :meth:`silpose.segment.BackgroundModel.fit` /
``segment_batch``. Errors are :class:`~silpose.app.errors.FramesInputError` naming the folder or file.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..errors import FramesInputError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
"""Image file suffixes read as frames (case-insensitive): the one list every camera input uses."""
VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm")
"""Video file suffixes read as a camera (case-insensitive; OpenCV's FFmpeg decodes them): the one list every
camera input uses (frames folders, recordings, ``silpose rig import``'s image-size probe)."""


def frame_size_text(shape) -> str:
    """``"<W>x<H> (WxH)"`` for an image shape (H, W[, C]), as error messages print frame sizes."""
    return f"{shape[1]}x{shape[0]} (WxH)"


def load_frames(folder, gray: bool = False) -> tuple[np.ndarray, list[str]]:
    """Read every PNG/JPG image of a folder, sorted by file name (plain string order: zero-pad
    frame numbers, ``frame_0002.png`` before ``frame_0010.png``).

    Parameters
    ----------
    folder : str or Path
    gray : bool
        Return graylevels: read in colour, then ``cv2.cvtColor(BGR2GRAY)`` - the conversion
        :class:`BackgroundModel` applies (``cv2.IMREAD_GRAYSCALE`` uses the codec's own and can
        differ by one level).

    Returns
    -------
    frames : array (N, H, W, 3) uint8 BGR, or (N, H, W) uint8 with ``gray``
    names : list of N file names (without the folder)
    """
    folder = Path(folder)
    if not folder.exists():
        raise FramesInputError(f"folder: {folder} does not exist")
    if not folder.is_dir():
        raise FramesInputError(f"folder: {folder} is not a directory")
    paths = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
    if not paths:
        raise FramesInputError(f"folder: no {'/'.join(s[1:] for s in IMAGE_SUFFIXES)} images in {folder}")
    frames = []
    for p in paths:
        img = cv2.imread(str(p), cv2.IMREAD_COLOR)
        if img is None:
            raise FramesInputError(f"{p}: cannot read this image (corrupt or not an image)")
        if gray:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        if frames and img.shape != frames[0].shape:
            raise FramesInputError(
                f"{p}: frame size {frame_size_text(img.shape)} differs from {paths[0].name} "
                f"({frame_size_text(frames[0].shape)})"
            )
        frames.append(img)
    return np.stack(frames), [p.name for p in paths]


def load_video(path, max_frames: int | None = None, gray: bool = False) -> np.ndarray:
    """Decode a video file with ``cv2.VideoCapture``.

    Parameters
    ----------
    path : str or Path
    max_frames : int or None
        Stop after this many frames.
    gray : bool
        Convert each frame to graylevel (``cv2.cvtColor``).

    Returns
    -------
    array (N, H, W, 3) uint8 BGR, or (N, H, W) uint8 with ``gray``; N >= 1.
    """
    path = Path(path)
    if not path.is_file():
        raise FramesInputError(f"path: video file {path} does not exist")
    if max_frames is not None and max_frames < 1:
        raise FramesInputError(f"max_frames: must be >= 1 or None, got {max_frames!r}")
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise FramesInputError(f"{path}: OpenCV cannot open this video")
        frames = []
        while max_frames is None or len(frames) < max_frames:
            ok, img = cap.read()
            if not ok:
                break
            if gray:
                img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
            frames.append(img)
    finally:
        cap.release()
    if not frames:
        raise FramesInputError(f"{path}: the video has no decodable frames")
    return np.stack(frames)
