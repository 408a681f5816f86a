"""The overlays' worker pipe (:mod:`.overlay_worker`, :class:`.overlay_video.OverlayWorker`): what a frame to
draw looks like on it.

A message is: a 4-byte little-endian length ``L``, ``L`` bytes of JSON (the header), then the raw bytes of the
arrays the header lists, in order. No pickle: the header holds only numbers, strings and the arrays' shapes and
types, and every field is checked on arrival. Headers:

- a frame to draw (:func:`.overlay_video.draw_frame`'s arguments): ``{"camera", "frame", "size": [w, h],
  "background": null | {"shape", "dtype"}, "people": [{"person", "status", "outline", "recon", "joints_px",
  "anchor_px"}], "name"}``, each array field null or its shape (float64). A {0, 1} mask background goes as
  ``"dtype": "bits"``: its pixels packed 8 to a byte (:func:`numpy.packbits`, row-major), an eighth of the bytes
  (a 644x486 mask: 39 kB instead of 313 kB, which the run writes and the worker reads each frame);
- an image already drawn: ``{"camera", "image": {"shape", "dtype"}, "name"}``.

``name`` is the PNG file (without ``.png``) the frame is tiled into (PNG overlays), else null.
"""

from __future__ import annotations

import json
import struct

import numpy as np

__all__ = ["ARRAY_FIELDS", "END", "pack", "pack_image", "read_message"]

#: the array fields of a person's drawing item (:func:`.overlay_video.draw_frame`), in the order they are sent
ARRAY_FIELDS = ("outline", "recon", "joints_px", "anchor_px")
_DTYPES = {"uint8": np.uint8, "float64": np.float64}
_BITS = "bits"  # a {0, 1} uint8 array sent packed 8 pixels to a byte (module docstring)
_LENGTH = struct.Struct("<I")
#: the message that ends the stream (length 0)
END = _LENGTH.pack(0)
#: bytes of a header at most (a frame's header is a few hundred bytes per person)
MAX_HEADER = 1 << 20


def _spec(a: np.ndarray) -> dict:
    return {"shape": list(a.shape), "dtype": str(a.dtype)}


def pack(camera: str, background: np.ndarray | None, size, frame: int, people: list[dict],
         name: str | None = None) -> list:
    """The message of a frame to draw: [length + header bytes, array, array, ...] (the arrays as they are, written
    by the caller after the header; ``background`` must not change until then). ``name``: the PNG file the frame
    goes into (PNG overlays), else None."""
    arrays, items = [], []
    back_spec = None
    if background is not None:
        background = np.ascontiguousarray(background, dtype=np.uint8)
        back_spec = _spec(background)
        if background.ndim == 2 and background.size and background.max() <= 1:  # a mask: 8 pixels to a byte
            back_spec["dtype"] = _BITS
            background = np.packbits(background, axis=None)
        arrays.append(background)
    for p in people:
        item = {"person": int(p["person"]), "status": str(p["status"])}
        for key in ARRAY_FIELDS:
            v = p.get(key)
            if v is None:
                item[key] = None
            else:
                a = np.ascontiguousarray(v, dtype=np.float64)
                item[key] = list(a.shape)
                arrays.append(a)
        items.append(item)
    header = {"camera": str(camera), "frame": int(frame), "size": [int(size[0]), int(size[1])],
              "background": back_spec, "people": items, "name": name}
    return [_framed(header)] + arrays


def pack_image(camera: str, image: np.ndarray, name: str | None = None) -> list:
    """The message of an image already drawn ((H, W, 3) uint8 BGR); ``name`` as for :func:`pack`."""
    image = np.ascontiguousarray(image, dtype=np.uint8)
    return [_framed({"camera": str(camera), "image": _spec(image), "name": name}), image]


def _framed(header: dict) -> bytes:
    body = json.dumps(header, separators=(",", ":")).encode()
    return _LENGTH.pack(len(body)) + body


def _read_exactly(stream, n: int) -> bytearray:
    buf = bytearray(n)
    view, got = memoryview(buf), 0
    while got < n:
        k = stream.readinto(view[got:])
        if not k:
            raise EOFError(f"the overlay pipe ended {n - got} bytes into a message")
        got += k
    return buf


def _read_array(stream, spec, dtype=None) -> np.ndarray:
    bits = False
    if isinstance(spec, dict):
        bits = spec.get("dtype") == _BITS
        shape, dtype = spec.get("shape"), np.uint8 if bits else _DTYPES.get(spec.get("dtype"))
        if dtype is None:
            raise ValueError(f"overlay message: array type {spec.get('dtype')!r} is not uint8, float64 or bits")
    else:
        shape = spec
    if not isinstance(shape, list) or not all(isinstance(s, int) and 0 <= s < 1 << 16 for s in shape):
        raise ValueError(f"overlay message: bad array shape {shape!r}")
    count = int(np.prod(shape, dtype=np.int64))
    if bits:
        packed = np.frombuffer(_read_exactly(stream, (count + 7) // 8), dtype=np.uint8)
        return np.unpackbits(packed, count=count).reshape(shape)
    return np.frombuffer(_read_exactly(stream, count * np.dtype(dtype).itemsize), dtype=dtype).reshape(shape)


def read_message(stream, cameras) -> tuple | None:
    """The next message on ``stream`` (a binary file): ``(camera, image, name)`` for an image, ``(camera,
    (background, size, camera, frame, people), name)`` for a frame to draw (``name``: the PNG file's, or None), or
    None at the end (a message of length 0). ValueError on a malformed message, EOFError when the stream ends inside
    one."""
    (n,) = _LENGTH.unpack(_read_exactly(stream, _LENGTH.size))
    if n == 0:
        return None
    if n > MAX_HEADER:
        raise ValueError(f"overlay message: a header of {n} bytes (at most {MAX_HEADER})")
    header = json.loads(_read_exactly(stream, n))
    camera = header.get("camera") if isinstance(header, dict) else None
    if camera not in cameras:
        raise ValueError(f"overlay message: unknown camera {camera!r}")
    name = header.get("name")
    bad_name = not isinstance(name, str) or not name or "/" in name or "\\" in name or name.startswith(".")
    if name is not None and bad_name:
        raise ValueError(f"overlay message: bad file name {name!r}")
    if "image" in header:
        return camera, _read_array(stream, header["image"]), name
    frame, size, people = header.get("frame"), header.get("size"), header.get("people")
    if not isinstance(frame, int) or not (isinstance(size, list) and len(size) == 2) or not isinstance(people, list):
        raise ValueError("overlay message: a frame needs 'frame', 'size' and 'people'")
    background = None if header.get("background") is None else _read_array(stream, header["background"])
    items = []
    for item in people:
        if not isinstance(item, dict) or not isinstance(item.get("person"), int) or not isinstance(item.get("status"), str):
            raise ValueError("overlay message: a person needs 'person' (int) and 'status' (str)")
        out = {"person": item["person"], "status": item["status"]}
        for key in ARRAY_FIELDS:
            out[key] = None if item.get(key) is None else _read_array(stream, item[key], np.float64)
        items.append(out)
    return camera, (background, (int(size[0]), int(size[1])), camera, frame, items), name
