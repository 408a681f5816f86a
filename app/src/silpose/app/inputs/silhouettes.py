"""Per-camera folders of silhouette images as ``silpose infer`` input.

Layout::

    INPUT/<camera name>/<frame>.png      one folder per camera, named as in the model's rig
                                         (.png, .bmp, .tif or .jpg: see :data:`MASK_SUFFIXES`)

Frames are matched by file name across cameras. A missing camera folder, a frame file absent from
one camera's folder, or an empty mask (no foreground pixel) is a missing view for that frame; the
model marginalises it. Foreground = grey value > ``threshold`` of the image as :func:`~.mask_images.mask_grey`
reads it (0/1 images, palettes, label maps and RGBA cut-outs included: its module doc). JPEG masks
(what many labs' background subtraction scripts save) get a 3x3 median first, like mask videos
(``silpose.app.recordings.silhouettes``): the codec smears 0/255 into grey edges and ringing. A frame name
present twice in one camera folder (``0001.png`` and ``0001.jpg``) is an error.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..contours import view_contour
from ..view_status import VIEW_OK
from ..errors import InferenceInputError
from .images import frame_order
from .mask_images import mask_grey


#: silhouette image suffixes read (case-insensitive); the lossy ones are median-filtered first
MASK_SUFFIXES = (".png", ".bmp", ".tif", ".tiff", ".jpg", ".jpeg")
LOSSY_SUFFIXES = (".jpg", ".jpeg")


def read_png_input(model, folder: Path, threshold: int = 127):
    """The contours of a folder of per-camera silhouette images (module doc), extracted at the model's n.

    Returns (frame names (N,), contours (N, K_rig, n, 2) px (NaN where missing),
    views_present (N, K_rig) bool, None).
    """
    if model.rig_ is None:
        raise InferenceInputError("the model file stores no rig, so camera folders cannot be named; use a dataset")
    names = list(model.rig_.names)
    subdirs = {p.name for p in folder.iterdir() if p.is_dir()}
    present_dirs = [n for n in names if n in subdirs]
    if not present_dirs:
        raise InferenceInputError(
            f"{folder}: neither a dataset (no .parquet files) nor a folder of silhouette images: expected subfolders named as the "
            f"model's cameras {names}, found {sorted(subdirs) or 'none'}"
        )
    files = {n: _mask_files(folder / n) for n in present_dirs}
    frames = sorted(set().union(*[set(f) for f in files.values()]), key=frame_order)
    if not frames:
        raise InferenceInputError(f"{folder}: the camera folders {present_dirs} hold no silhouette images "
                                  f"({', '.join(MASK_SUFFIXES)})")
    n_pts = model.layout_.n_points
    contours = np.full((len(frames), len(names), n_pts, 2), np.nan)
    present = np.zeros((len(frames), len(names)), dtype=bool)
    for k, cam_name in enumerate(names):
        cam = model.rig_[k]
        for i, frame in enumerate(frames):
            path = files.get(cam_name, {}).get(frame)
            if path is None:
                continue
            img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
            if img is None:
                raise InferenceInputError(f"{path}: not a readable image")
            if img.shape[:2] != (cam.height, cam.width):
                raise InferenceInputError(
                    f"{path}: image is {img.shape[1]}x{img.shape[0]}, camera {cam_name!r} is {cam.width}x{cam.height}"
                )
            img = mask_grey(img)
            if path.suffix.lower() in LOSSY_SUFFIXES:
                img = cv2.medianBlur(img, 3)
            points, status, _ = view_contour(img > threshold, n_pts)
            if status == VIEW_OK:
                contours[i, k] = points
                present[i, k] = True
    return np.array(frames), contours, present, None


def _mask_files(camera_folder: Path) -> dict[str, Path]:
    """{frame name: file} of one camera folder's silhouette images; a name present twice is an error."""
    out: dict[str, Path] = {}
    for p in sorted(camera_folder.iterdir()):
        if p.is_file() and p.suffix.lower() in MASK_SUFFIXES:
            if p.stem in out:
                raise InferenceInputError(f"{p}: frame {p.stem!r} is also {out[p.stem].name} in this camera folder; "
                                          "keep one file per frame")
            out[p.stem] = p
    return out
