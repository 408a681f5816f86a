"""OpenCV ``cv2.FileStorage`` calibration files (XML or YAML), in the spellings people use.

Layouts:

- one camera per file: the fields at the top level; the camera is named by a ``name`` field, else
  by the file's stem (``cam1.xml`` is ``cam1``);
- several cameras per file: top-level maps (``cam0:``, ``cam1:`` ...) each holding the fields,
  named by their ``name`` field or else their key, in file order.

Fields (spelling-insensitive, :data:`.calibration.FIELD_ALIASES`): camera matrix (``camera_matrix``,
``cameraMatrix``, ``CameraMatrix``, ``K``, ``M``, ``intrinsic(s)``), distortion
(``distortion_coefficients``, ``dist_coeffs``, ``DistortionCoeffs``, ``dist``, ``D``; zeros if
absent), rotation as a Rodrigues vector or a 3x3 matrix (``rotation_vector(s)``, ``rvec(s)``,
``RVector``, ``Rotation``, ``R``, ``rotation_matrix``), translation (``translation_vector(s)``,
``tvec(s)``, ``TVector``, ``Translation``, ``T``, ``t``), image size (``image_size`` [w, h] or
``image_width`` + ``image_height``; optional), name. Values are ``!!opencv-matrix`` nodes or plain
sequences. The pose maps the calibration's world to the camera, in its length unit. Keys silpose
does not read are listed in the error when a required field is missing.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from silpose.shared.atomic import atomic_path
from silpose.shared.camera import RigError

from .calibration import CalibratedCamera, FieldReader, rotation_to_rvec

__all__ = ["read_opencv", "write_opencv_camera", "open_filestorage", "node_value", "DEFAULT_KEYS"]

#: Keys :func:`write_opencv_camera` writes by default (OpenCV's own sample spelling).
DEFAULT_KEYS = {"name": "name", "width": "image_width", "height": "image_height", "K": "camera_matrix",
                "dist": "distortion_coefficients", "rvec": "rvec", "R": "rotation_matrix", "t": "tvec"}


@contextmanager
def open_filestorage(path: str | Path) -> Iterator[cv2.FileNode]:
    """The root node of a FileStorage file; RigError naming the file if it cannot be read."""
    source = str(path)
    if not Path(path).is_file():
        raise RigError(f"{source}: calibration file not found")
    try:
        fs = cv2.FileStorage(source, cv2.FILE_STORAGE_READ)
        opened = fs.isOpened()
    except (cv2.error, SystemError) as exc:
        raise RigError(f"{source}: not a readable OpenCV FileStorage file ({type(exc).__name__})") from None
    if not opened:
        raise RigError(f"{source}: not a readable OpenCV FileStorage file")
    try:
        root = fs.root()
        if not root.isMap():
            raise RigError(f"{source}: top level is not a map of fields")
        yield root
    finally:
        fs.release()


def node_value(node, where: str):
    """A FileNode as a float array (numbers, sequences, matrices), a str, or None (other maps)."""
    try:
        if node.isMap():
            if {"rows", "cols", "data"} <= set(node.keys()):
                return np.asarray(node.mat(), dtype=np.float64)
            return None
        if node.isSeq():
            items = [node_value(node.at(i), where) for i in range(node.size())]
            if any(v is None or isinstance(v, str) for v in items):
                raise RigError(f"{where}: expected numbers, found a sequence of non-numbers")
            return np.asarray(items, dtype=np.float64)
        if node.isInt() or node.isReal():
            return np.asarray(node.real(), dtype=np.float64)
        if node.isString():
            return node.string()
    except (cv2.error, ValueError) as exc:
        if isinstance(exc, RigError):
            raise
        raise RigError(f"{where}: malformed value ({str(exc).strip().splitlines()[-1]})") from None
    return None


def _reader(node, source: str, where: str = "") -> FieldReader:
    return FieldReader(tuple(node.keys()), lambda k: node_value(node.getNode(k), f"{source}: field {where}{k}"),
                       source, where)


def read_opencv(path: str | Path) -> list[CalibratedCamera]:
    """The cameras of one OpenCV calibration file (module docstring), in file order."""
    source = str(path)
    with open_filestorage(path) as root:
        top = _reader(root, source)
        if top.matches("camera matrix"):
            return [top.camera(Path(path).stem)]
        cams = []
        for key in top.keys:
            node = root.getNode(key)
            if node.isMap():
                sub = _reader(node, source, f"{key}.")
                if sub.matches("camera matrix"):
                    cams.append(sub.camera(key))
        if not cams:
            raise top.missing("camera matrix")
        return cams


def write_opencv_camera(path: str | Path, camera: CalibratedCamera, keys: dict[str, str] | None = None,
                        rotation: str = "rvec") -> None:
    """Write one camera as an OpenCV FileStorage file (format from the suffix: .xml, .yml, .yaml).

    ``keys`` renames the written fields (defaults :data:`DEFAULT_KEYS`; a key mapped to ``None`` is
    left out, e.g. ``{"width": None, "height": None}`` for a file without image size).
    ``rotation`` is ``"rvec"`` (Rodrigues), ``"matrix"`` or ``"both"``. Written atomically.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".xml", ".yml", ".yaml"):
        raise RigError(f"{path}: OpenCV calibration files must end in .xml, .yml or .yaml")
    if rotation not in ("rvec", "matrix", "both"):
        raise ValueError(f"rotation must be 'rvec', 'matrix' or 'both', got {rotation!r}")
    k = {**DEFAULT_KEYS, **(keys or {})}
    fmt = cv2.FILE_STORAGE_FORMAT_XML if suffix == ".xml" else cv2.FILE_STORAGE_FORMAT_YAML
    with atomic_path(path) as tmp:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE | fmt)
        try:
            values = [("name", camera.name), ("K", np.asarray(camera.K, np.float64)),
                      ("dist", np.asarray(camera.dist, np.float64).reshape(-1, 1))]
            if camera.size is not None:
                values += [("width", int(camera.size[0])), ("height", int(camera.size[1]))]
            if rotation in ("rvec", "both"):
                values.append(("rvec", rotation_to_rvec(camera.R).reshape(3, 1)))
            if rotation in ("matrix", "both"):
                values.append(("R", np.asarray(camera.R, np.float64)))
            values.append(("t", np.asarray(camera.t, np.float64).reshape(3, 1)))
            for field, value in values:
                if k.get(field):
                    fs.write(k[field], value)
        finally:
            fs.release()
