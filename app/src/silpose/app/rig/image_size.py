"""The image size of each camera: from the file, from ``--image-size``, or from an image or video next to it.

Calibration files rarely state the image size. In order:

1. the file's own size (``image_size``, ``image_width`` + ``image_height``, Pose2Sim ``size``,
   EasyMocap ``W_``/``H_``); ``--image-size`` must then agree with it;
2. ``--image-size WxH``, or per camera ``--image-size 54138969=1000x1002,1000x1000`` (``name=WxH`` entries,
   and optionally one bare ``WxH`` for the cameras not named);
3. an image or a video of that camera near the calibration file: in its folder or up to two
   folders below, a file whose stem, or whose folder, is the camera's name (spelling-insensitive:
   ``cam_01`` matches ``cam01.mp4`` and ``images/cam_01/000000.jpg``) or holds it as whole words
   (:func:`silpose.app.camera_names.camera_in_stem`: Human3.6M's ``Walking.54138969.mp4``); failing that,
   the images and videos in the calibration file's own folder if they all have one size.

Otherwise a one-line error says what to pass.
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2

from silpose.shared.camera import RigError

from ..camera_names import camera_in_stem
from ..inputs.images import IMAGE_SUFFIXES, VIDEO_SUFFIXES, display_rotation
from .calibration import CalibratedCamera, normalise_key

__all__ = ["parse_image_size", "parse_image_sizes", "media_size", "find_media", "resolve_image_size", "MEDIA_SUFFIXES"]

MEDIA_SUFFIXES = IMAGE_SUFFIXES + VIDEO_SUFFIXES
_MAX_FILES = 20_000  # files looked at near one calibration file


def parse_image_size(text: str, what: str = "--image-size") -> tuple[int, int]:
    """``"644x486"`` -> (644, 486)."""
    parts = str(text).lower().replace("×", "x").split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise RigError(f"{what}: expected WIDTHxHEIGHT in pixels (e.g. 644x486), got {text!r}") from None
    if w <= 0 or h <= 0:
        raise RigError(f"{what}: width and height must be positive, got {text!r}")
    return w, h


def parse_image_sizes(text: str, cameras, what: str = "--image-size") -> dict[str, tuple[int, int]]:
    """``"54138969=1000x1002,1000x1000"`` -> the size of every camera in ``cameras`` that gets one: named
    entries for their cameras, a bare ``WxH`` for all others (module docstring). RigError for a name that is
    not a camera, a camera named twice or two bare sizes."""
    names = list(cameras)
    out: dict[str, tuple[int, int]] = {}
    default = None
    for entry in (e.strip() for e in str(text).split(",")):
        if not entry:
            continue
        name, eq, size = entry.rpartition("=")
        if not eq:
            if default is not None:
                raise RigError(f"{what}: two sizes for the cameras not named ({text!r}); name them: cam=WxH")
            default = parse_image_size(entry, what)
            continue
        name = name.strip()
        if name not in names:
            raise RigError(f"{what}: {name!r} is not a camera of the calibration ({', '.join(names)})")
        if name in out:
            raise RigError(f"{what}: camera {name!r} is given two sizes")
        out[name] = parse_image_size(size, f"{what} {name}")
    if default is None and not out:
        raise RigError(f"{what}: expected WIDTHxHEIGHT or camera=WIDTHxHEIGHT entries separated by commas, got {text!r}")
    if default is not None:
        out = {n: out.get(n, default) for n in names}
    return out


def media_size(path: Path) -> tuple[int, int] | None:
    """(width, height) of an image or the first frame size of a video, upright when the video's metadata rotates it
    (``silpose.app.recordings.sources``, "Orientation"); None if unreadable."""
    if path.suffix.lower() in IMAGE_SUFFIXES:
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        return None if img is None else (int(img.shape[1]), int(img.shape[0]))
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            return None
        cap.set(cv2.CAP_PROP_ORIENTATION_AUTO, 0.0)  # the stored size (OpenCV's default differs between builds)
        w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        if display_rotation(cap) % 180 == 90:  # a phone's portrait video: upright, as players and recordings read it
            w, h = h, w
        return (w, h) if w > 0 and h > 0 else None
    finally:
        cap.release()


def _media_near(folder: Path, depth: int = 2) -> list[Path]:
    out: list[Path] = []
    base = len(folder.parts)
    for root, dirs, files in os.walk(folder):
        dirs.sort()
        if len(Path(root).parts) - base >= depth:
            dirs[:] = []
        out += [Path(root) / f for f in sorted(files) if Path(f).suffix.lower() in MEDIA_SUFFIXES]
        if len(out) > _MAX_FILES:
            break
    return out


def find_media(folder: Path, camera_name: str) -> list[Path]:
    """Images/videos near ``folder`` named after ``camera_name`` (stem or parent folder; module docstring)."""
    key = normalise_key(camera_name)
    exact = [p for p in _media_near(folder) if key and key in (normalise_key(p.stem), normalise_key(p.parent.name))]
    return exact or [p for p in _media_near(folder)
                     if camera_in_stem(p.stem, [camera_name]) or camera_in_stem(p.parent.name, [camera_name])]


def resolve_image_size(cam: CalibratedCamera, option: tuple[int, int] | None) -> tuple[tuple[int, int], str]:
    """(width, height) of ``cam`` and where it came from (module docstring)."""
    if cam.size is not None:
        if option is not None and tuple(option) != tuple(cam.size):
            raise RigError(
                f"{cam.source}: camera {cam.name!r}: conflicting image sizes: the file says {cam.size[0]}x{cam.size[1]}, "
                f"--image-size says {option[0]}x{option[1]}"
            )
        return tuple(cam.size), "the calibration file"
    if option is not None:
        return tuple(option), "--image-size"
    folder = Path(cam.source).parent
    for p in find_media(folder, cam.name):
        size = media_size(p)
        if size is not None:
            return size, str(p)
    here = [p for p in _media_near(folder, depth=0)]
    sizes = {s for s in (media_size(p) for p in here) if s is not None}
    if len(sizes) == 1:
        return sizes.pop(), f"the images/videos in {folder}"
    raise RigError(
        f"{cam.source}: camera {cam.name!r}: image size unknown: the file has none (image_width + image_height or "
        "image_size) and no image or video of this camera is next to it; pass --image-size WIDTHxHEIGHT"
    )
