"""Input checks and graylevel conversion shared by the background model and the loaders.

Every error is a :class:`SegmentError` (a ``ValueError``) whose message starts with the name of
the offending argument, e.g. ``"frames: expected dtype uint8, got float64"``.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np


class SegmentError(ValueError):
    """Bad input to silpose.segment (the message names the argument or the file)."""


def as_frame_stack(frames, name: str = "frames") -> np.ndarray:
    """Validate a stack of frames and return it as an array.

    Parameters
    ----------
    frames : array (N, H, W) or (N, H, W, 3) uint8, or a sequence of N arrays (H, W) / (H, W, 3)
        Graylevel or colour frames; colour is BGR, as read by ``cv2.imread``.
    name : str
        Argument name used in error messages.

    Returns
    -------
    array (N, H, W) or (N, H, W, 3) uint8
    """
    if isinstance(frames, (list, tuple)):
        if len(frames) == 0:
            raise SegmentError(f"{name}: no frames given (empty sequence)")
        items = [np.asarray(f) for f in frames]
        for i, item in enumerate(items):
            _check_single(item, f"{name}[{i}]")
            if item.shape[:2] != items[0].shape[:2]:
                raise SegmentError(
                    f"{name}[{i}]: frame size {_size(item)} differs from {name}[0] size {_size(items[0])}"
                )
            if item.ndim != items[0].ndim:
                raise SegmentError(f"{name}[{i}]: mixes graylevel and colour frames ({name}[0] has shape {items[0].shape})")
        return np.stack(items)
    arr = np.asarray(frames)
    if arr.ndim not in (3, 4):
        raise SegmentError(
            f"{name}: expected a stack of frames with shape (N, H, W) or (N, H, W, 3), got shape {arr.shape}"
        )
    if arr.shape[0] == 0:
        raise SegmentError(f"{name}: no frames given (N = 0)")
    _check_single(arr[0], f"{name}[0]")
    return arr


def as_single_frame(frame, name: str = "frame") -> np.ndarray:
    """Validate one frame (H, W) or (H, W, 3) uint8 and return it as an array."""
    arr = np.asarray(frame)
    _check_single(arr, name)
    return arr


def _check_single(arr: np.ndarray, name: str) -> None:
    if arr.dtype != np.uint8:
        raise SegmentError(f"{name}: expected dtype uint8, got {arr.dtype}")
    if arr.ndim == 3 and arr.shape[2] != 3:
        raise SegmentError(f"{name}: colour frames need 3 channels (BGR), got shape {arr.shape}")
    if arr.ndim not in (2, 3):
        raise SegmentError(f"{name}: expected a frame of shape (H, W) or (H, W, 3), got shape {arr.shape}")
    if arr.shape[0] < 1 or arr.shape[1] < 1:
        raise SegmentError(f"{name}: empty frame of shape {arr.shape}")


def _size(arr: np.ndarray) -> str:
    return f"{arr.shape[1]}x{arr.shape[0]} (WxH)"


def frame_size_text(shape: Sequence[int]) -> str:
    """'WxH (WxH)' text for an (H, W) shape, used in messages."""
    return f"{shape[1]}x{shape[0]} (WxH)"


def to_gray(frames: np.ndarray) -> np.ndarray:
    """Graylevel of validated frames.

    Parameters
    ----------
    frames : array (N, H, W) or (N, H, W, 3) uint8 (BGR)

    Returns
    -------
    array (N, H, W) uint8, C-contiguous. Colour goes through ``cv2.cvtColor(COLOR_BGR2GRAY)``
    (Y = 0.299 R + 0.587 G + 0.114 B, rounded), applied to the whole stack at once.
    """
    if frames.ndim == 3:
        return np.ascontiguousarray(frames)
    n, h, w, _ = frames.shape
    flat = np.ascontiguousarray(frames).reshape(n * h, w, 3)
    return cv2.cvtColor(flat, cv2.COLOR_BGR2GRAY).reshape(n, h, w)
