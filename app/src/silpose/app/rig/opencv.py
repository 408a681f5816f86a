"""OpenCV ``cv2.FileStorage`` calibration files (XML or YAML), in the spellings people use.

Layouts:

- one camera per file: the fields at the top level; the camera is named by a ``name`` field, else
  by the file's stem (``cam1.xml`` is ``cam1``);
- several cameras per file: top-level maps (``cam0:``, ``cam1:`` ...) each holding the fields,
  named by their ``name`` field or else their key, in file order;
- a ``cv2.stereoCalibrate`` pair: ``K1``, ``D1``, ``K2``, ``D2`` (or ``cameraMatrix1``, ``distCoeffs1`` ...), ``R``,
  ``T``: cameras ``cam1`` (the world is its frame) and ``cam2``.

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

from .calibration import CalibratedCamera, FieldReader, camera_matrix, distortion, rotation_from_values, rotation_to_rvec

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
    if Path(path).stat().st_size == 0:
        raise RigError(f"{source}: not a readable OpenCV FileStorage file (the file is empty)")
    # the text is read here and given to OpenCV from memory: a byte-order mark or CRLF line ends (a Windows editor's
    # save) make OpenCV's own reader fail, and plain YAML (ROS, hand-written) needs OpenCV's header
    try:
        text = Path(path).read_text(encoding="utf-8-sig").replace("\r\n", "\n")
    except (OSError, UnicodeDecodeError) as exc:
        raise RigError(f"{source}: cannot read this file as text ({exc})") from None
    xml = text.lstrip().startswith("<")
    if not xml and not text.lstrip().startswith("%YAML"):
        text = "%YAML:1.0\n---\n" + text
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY
                             | (cv2.FILE_STORAGE_FORMAT_XML if xml else cv2.FILE_STORAGE_FORMAT_YAML))
        opened = fs.isOpened()
    except (cv2.error, SystemError):
        opened = False
    if not opened:
        kind = "YAML" if Path(path).suffix.lower() in (".yml", ".yaml") else "XML" if Path(path).suffix.lower() == ".xml" else "file"
        raise RigError(f"{source}: not a readable OpenCV FileStorage file (OpenCV cannot parse this {kind}; expected "
                       "XML, or YAML such as 'camera_matrix: !!opencv-matrix {rows: 3, cols: 3, dt: d, data: [...]}')")
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
                return _matrix(node, where)
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


def _matrix(node, where: str) -> np.ndarray:
    """An ``!!opencv-matrix`` / ``type_id="opencv-matrix"`` node as a (rows, cols) float array, read element by
    element: ``FileNode.mat()`` of OpenCV 4.11 turns integers written in a ``dt: d`` matrix (``data: [0, 0, 1]``,
    common in hand-written files) into garbage such as 4.29e9, while each element's ``real()`` is right."""
    rows, cols, data = node.getNode("rows"), node.getNode("cols"), node.getNode("data")
    if not (rows.isInt() or rows.isReal()) or not (cols.isInt() or cols.isReal()):
        raise RigError(f"{where}: matrix rows and cols must be numbers")
    r, c = int(rows.real()), int(cols.real())
    if data.isSeq():
        values = [data.at(i) for i in range(data.size())]
    elif data.isInt() or data.isReal():
        values = [data]
    else:
        raise RigError(f"{where}: matrix data must be a sequence of numbers")
    if not all(v.isInt() or v.isReal() for v in values):
        raise RigError(f"{where}: matrix data must be numbers")
    channels = max(1, len(values) // max(1, r * c))
    if r < 0 or c < 0 or len(values) != r * c * channels:
        raise RigError(f"{where}: matrix of {r}x{c} has {len(values)} values")
    arr = np.array([v.real() for v in values], dtype=np.float64)
    return arr.reshape(r, c) if channels == 1 else arr.reshape(r, c, channels)


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
        stereo = _stereo_pair(root, source)
        if stereo is not None:
            return stereo
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


def _stereo_pair(root, source: str) -> list[CalibratedCamera] | None:
    """The two cameras of a ``cv2.stereoCalibrate`` file (``K1``/``cameraMatrix1``, ``D1``/``distCoeffs1``, ``K2``,
    ``D2``, ``R``, ``T``; optional ``image_size``), named ``cam1`` and ``cam2``, or None if it is not one. The world
    is camera 1's frame (identity pose); camera 2's pose is ``[R | T]``."""
    get = lambda k: node_value(root.getNode(k), f"{source}: field {k}")  # noqa: E731
    keys = tuple(root.keys())
    first = FieldReader(keys, get, source, suffix="1")
    second = FieldReader(keys, get, source, suffix="2")
    if not (first.matches("camera matrix") and second.matches("camera matrix")):
        return None
    pose = FieldReader(keys, get, source)
    _, R = pose.agreed("rotation", pose.numbers("rotation"), rotation_from_values, 1e-6)
    _, t = pose.agreed("translation", pose.numbers("translation"), lambda v, w: _three(v, w), 1e-9)
    size = pose.image_size()
    cams = []
    for name, reader, (R_k, t_k) in (("cam1", first, (np.eye(3), np.zeros(3))), ("cam2", second, (R, t))):
        _, K = reader.agreed("camera matrix", reader.numbers("camera matrix"), camera_matrix, 1e-9)
        dists = reader.numbers("distortion", required=False)
        dist = reader.agreed("distortion", dists, distortion, 1e-12)[1] if dists else np.zeros(5)
        cams.append(CalibratedCamera(name=name, K=K, dist=dist, R=R_k, t=t_k, size=size, source=source))
    return cams


def _three(value: np.ndarray, where: str) -> np.ndarray:
    if value.size != 3:
        raise RigError(f"{where}: expected 3 values (the translation from camera 1 to camera 2), got shape {value.shape}")
    return value.ravel()


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
    if camera.fisheye:
        raise ValueError(f"camera {camera.name!r}: OpenCV calibration files do not say that a lens is a fisheye")
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
