"""Silhouette masks as 1-bit PNG files: the ``masks`` column of dataset format version 2.

A mask is an (H, W) uint8 array of 0/1 (1 = person). It is stored losslessly as a 1-bit greyscale
PNG (OpenCV ``IMWRITE_PNG_BILEVEL``, zlib level 6), so image viewers and Hugging Face's dataset
viewer show it as a black-and-white picture. Measured on the default preset (2,500 samples, 4 x
320x240 raster masks each, 2 cores): ~1.3 KB of PNG per sample (~1.1 KB after the shard's zstd);
``load_split(..., columns=["masks"])`` takes 0.46 ms per sample (format 1's uint8 tensor column:
2.2 ms, its list levels are slow to decode), and a whole shard is written in 0.7 ms per sample
(format 1: 3.6 ms) and is 35 % smaller (5.8 KB per sample, floats byte-stream-split).

Decoding accepts any single-channel PNG of the right size (1-bit as written here, or an 8-bit
0/1 or 0/255 image from another tool): every nonzero pixel is foreground.
"""

from __future__ import annotations

import cv2
import numpy as np

#: OpenCV parameters of :func:`encode_mask`: 1-bit greyscale, zlib level 6.
PNG_PARAMS = (cv2.IMWRITE_PNG_BILEVEL, 1, cv2.IMWRITE_PNG_COMPRESSION, 6)


def encode_mask(mask: np.ndarray) -> bytes:
    """The 1-bit PNG file of ``mask`` (H, W) with values 0/1.

    Raises ValueError for another shape or other values (a 1-bit PNG holds only 0/1).
    """
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"a mask must be (H, W), got shape {mask.shape}")
    if mask.size and (mask.min() < 0 or mask.max() > 1):
        raise ValueError("a mask must hold only 0 and 1")
    ok, buf = cv2.imencode(".png", mask.astype(np.uint8, copy=False), list(PNG_PARAMS))
    if not ok:  # pragma: no cover - OpenCV fails only on impossible sizes
        raise ValueError(f"OpenCV could not encode a mask of shape {mask.shape} as PNG")
    return buf.tobytes()


def decode_mask_into(data: np.ndarray | bytes, out: np.ndarray) -> None:
    """Decode one PNG file ``data`` (bytes or a uint8 buffer) into ``out`` (H, W) uint8 as 0/1.

    Raises ValueError if ``data`` is not a PNG/image OpenCV reads, or not single-channel (H, W).
    """
    buf = np.frombuffer(data, np.uint8) if isinstance(data, (bytes, bytearray, memoryview)) else data
    img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED) if buf.size else None
    if img is None:
        raise ValueError("not a readable PNG image")
    if img.shape != out.shape or img.dtype != np.uint8:
        raise ValueError(f"expected a single-channel 8-bit image of shape {out.shape}, got {img.dtype} {img.shape}")
    np.not_equal(img, 0, out=out.view(np.bool_))


def decode_mask(data: np.ndarray | bytes, height: int, width: int) -> np.ndarray:
    """(H, W) uint8 0/1 mask from one PNG file (see :func:`decode_mask_into`)."""
    out = np.empty((height, width), np.uint8)
    decode_mask_into(data, out)
    return out
