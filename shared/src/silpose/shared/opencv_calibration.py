"""Read and write camera calibrations in OpenCV ``cv2.FileStorage`` files (XML or YAML).

Supported layouts:

- one camera per file: the fields below at the top level of the file;
- several cameras per file: top-level maps (e.g. ``cam0:``, ``cam1:``), each holding the fields
  below; each map's key is the camera's name unless the map has its own ``name`` field.
  Cameras come in file order.

Fields (first key found wins; keys are case-sensitive):

=============== ============================================================ =========
field           keys                                                         required
=============== ============================================================ =========
camera matrix   ``camera_matrix``, ``cameraMatrix``, ``K``, ``M`` (3x3)       yes
distortion      ``distortion_coefficients``, ``dist_coeffs``, ``distCoeffs``, no (zeros)
                ``D``, ``dist`` (4, 5, 8, 12 or 14 values)
rotation        ``rvec``, ``rotation_vector`` (3 values, Rodrigues) or        yes
                ``R``, ``rotation_matrix``, ``rotation`` (3x3), world->camera
translation     ``tvec``, ``T``, ``t``, ``translation`` (3 values), world->   yes
                camera, in file units; multiplied by ``unit`` to get metres
image size      ``image_width`` + ``image_height``, or ``image_size`` /       yes
                ``imageSize`` as [width, height]
name            ``name``, ``camera_name`` (string)                           no
=============== ============================================================ =========

Values may be ``!!opencv-matrix`` nodes or plain sequences. If both a rotation vector and a
rotation matrix are present they must agree (1e-6). Every problem raises
:class:`silpose.shared.pinhole.RigError` (re-exported by :mod:`silpose.shared.camera`) with a one-line message naming the file and the field.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from .atomic import atomic_path
from .pinhole import Camera, RigError

__all__ = ["read_opencv_cameras", "write_opencv_camera", "rotation_to_rvec"]

K_KEYS = ("camera_matrix", "cameraMatrix", "K", "M")
DIST_KEYS = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "D", "dist")
RVEC_KEYS = ("rvec", "rotation_vector")
RMAT_KEYS = ("R", "rotation_matrix", "rotation")
T_KEYS = ("tvec", "T", "t", "translation")
SIZE_KEYS = ("image_size", "imageSize")
NAME_KEYS = ("name", "camera_name")
CAMERA_KEYS = K_KEYS  # a map holding one of these is a camera
_DIST_SIZES = (4, 5, 8, 12, 14)


def _node_value(node, where: str):
    """A FileNode as a numpy array (numbers, sequences, matrices), a str, or None (other maps)."""
    try:
        if node.isMap():
            if {"rows", "cols", "data"} <= set(node.keys()):
                return np.asarray(node.mat(), dtype=np.float64)
            return None
        if node.isSeq():
            items = [_node_value(node.at(i), where) for i in range(node.size())]
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


class _Fields:
    """Named values of one FileStorage map, with errors that name the file and the field."""

    def __init__(self, node, source: str, prefix: str = ""):
        self.node = node
        self.source = source
        self.prefix = prefix
        self.keys = tuple(node.keys())

    def where(self, key: str) -> str:
        return f"{self.source}: field {self.prefix}{key}"

    def find(self, keys: tuple[str, ...]) -> str | None:
        return next((k for k in keys if k in self.keys), None)

    def array(self, keys: tuple[str, ...], shape: tuple[int, ...] | None, what: str, required: bool = True):
        key = self.find(keys)
        if key is None:
            if required:
                raise RigError(f"{self.source}: missing field {self.prefix}{what} (one of {', '.join(keys)})")
            return None, None
        value = _node_value(self.node.getNode(key), self.where(key))
        if value is None or isinstance(value, str):
            raise RigError(f"{self.where(key)}: expected numbers")
        if shape is not None and value.size != int(np.prod(shape)):
            raise RigError(f"{self.where(key)}: expected {'x'.join(map(str, shape))} values, got shape {value.shape}")
        if not np.all(np.isfinite(value)):
            raise RigError(f"{self.where(key)}: contains NaN or infinity")
        return (value.reshape(shape) if shape is not None else value.ravel()), key

    def string(self, keys: tuple[str, ...]) -> str | None:
        key = self.find(keys)
        if key is None:
            return None
        value = _node_value(self.node.getNode(key), self.where(key))
        if not isinstance(value, str):
            raise RigError(f"{self.where(key)}: expected a string")
        return value


def _check_rotation(R: np.ndarray, where: str) -> None:
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0:
        raise RigError(f"{where}: not a rotation matrix (R R^T != I or det(R) != +1)")


def rotation_to_rvec(R: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) -> Rodrigues vector (3,) = angle * unit axis, accurate to ~1e-16 at any angle.

    ``cv2.Rodrigues`` loses about 1e-8 near an angle of pi (a camera facing -x, like the default
    rig's cam2). Here (Rodrigues' formula ``R = cos(th) I + sin(th) [a]x + (1 - cos(th)) a a^T``):
    ``sin(th) a = vee(R - R^T) / 2``, ``cos(th) = (tr R - 1) / 2``, ``th = atan2(|sin(th) a|, cos(th))``;
    for th > 90 deg the axis comes from the symmetric part ``(R + R^T)/2 - cos(th) I = (1 - cos(th)) a a^T``
    (its largest column), its sign from ``sin(th) a``.
    """
    R = np.asarray(R, dtype=np.float64)
    sin_a = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    cos_th = 0.5 * (np.trace(R) - 1.0)
    sin_th = np.linalg.norm(sin_a)
    th = np.arctan2(sin_th, cos_th)
    if th == 0.0:
        return np.zeros(3)
    if cos_th >= 0.0:
        return th * sin_a / sin_th
    S = 0.5 * (R + R.T) - cos_th * np.eye(3)  # (1 - cos th) a a^T
    k = int(np.argmax(np.diag(S)))
    axis = S[:, k] / np.linalg.norm(S[:, k])
    if axis @ sin_a < 0:
        axis = -axis
    return th * axis


def _as_int(value: float, where: str) -> int:
    if value != np.round(value) or value <= 0:
        raise RigError(f"{where}: expected a positive integer, got {value}")
    return int(value)


def _read_camera(fields: _Fields, name: str, unit: float) -> Camera:
    K, _ = fields.array(K_KEYS, (3, 3), "camera matrix")
    dist, dkey = fields.array(DIST_KEYS, None, "distortion", required=False)
    if dist is None:
        dist = np.zeros(5)
    elif dist.size not in _DIST_SIZES:
        raise RigError(f"{fields.where(dkey)}: expected 4, 5, 8, 12 or 14 coefficients, got {dist.size}")
    rvec, rvkey = fields.array(RVEC_KEYS, (3,), "rotation", required=False)
    Rm, rmkey = fields.array(RMAT_KEYS, (3, 3), "rotation", required=False)
    if rvec is None and Rm is None:
        raise RigError(
            f"{fields.source}: missing field {fields.prefix}rotation (one of {', '.join(RVEC_KEYS + RMAT_KEYS)})"
        )
    if Rm is not None:
        _check_rotation(Rm, fields.where(rmkey))
    if rvec is not None:
        R_from_vec = cv2.Rodrigues(rvec.reshape(3, 1))[0]
        if Rm is not None and not np.allclose(R_from_vec, Rm, atol=1e-6):
            raise RigError(f"{fields.where(rvkey)}: disagrees with field {fields.prefix}{rmkey}")
        R = Rm if Rm is not None else R_from_vec
    else:
        R = Rm
    t, _ = fields.array(T_KEYS, (3,), "translation")
    if "image_width" in fields.keys or "image_height" in fields.keys:
        w, _ = fields.array(("image_width",), (1,), "image_width")
        h, _ = fields.array(("image_height",), (1,), "image_height")
        width = _as_int(float(w[0]), fields.where("image_width"))
        height = _as_int(float(h[0]), fields.where("image_height"))
    else:
        size, skey = fields.array(SIZE_KEYS, (2,), "image size (image_width + image_height, or image_size)")
        width = _as_int(float(size[0]), fields.where(skey) + " [width]")
        height = _as_int(float(size[1]), fields.where(skey) + " [height]")
    name = fields.string(NAME_KEYS) or name
    try:
        return Camera(name=name, K=K, R=R, t=t * unit, width=width, height=height, dist=dist)
    except RigError as exc:
        raise RigError(f"{fields.source}: {exc}") from None


def read_opencv_cameras(path: str | Path, unit: float = 1.0, default_name: str = "cam0") -> list[Camera]:
    """Cameras from one OpenCV FileStorage calibration file (XML or YAML, see the module doc).

    Args:
        path: the ``.xml`` / ``.yml`` / ``.yaml`` file.
        unit: factor from the file's translation unit to metres (0.001 for millimetres).
        default_name: name of a single camera that has no ``name`` field.
    Returns:
        the cameras in file order (one for a one-camera file).
    Raises:
        RigError: unreadable file, missing field, wrong shape, not a rotation, etc.
    """
    source = str(path)
    if not (np.isfinite(unit) and unit > 0):
        raise RigError(f"{source}: unit must be a positive number, got {unit}")
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
        top = _Fields(root, source)
        if top.find(CAMERA_KEYS) is not None:
            return [_read_camera(top, default_name, unit)]
        cams = []
        for key in top.keys:
            node = root.getNode(key)
            if node.isMap() and _Fields(node, source).find(CAMERA_KEYS) is not None:
                cams.append(_read_camera(_Fields(node, source, prefix=f"{key}."), key, unit))
        if not cams:
            raise RigError(f"{source}: missing field camera matrix (one of {', '.join(K_KEYS)})")
        return cams
    finally:
        fs.release()


def write_opencv_camera(path: str | Path, camera: Camera, unit: float = 1.0, rotation: str = "rvec") -> None:
    """Write one camera as an OpenCV FileStorage file readable by :func:`read_opencv_cameras`.

    The format follows the suffix (``.xml``, ``.yml``, ``.yaml``). Fields written: ``name``,
    ``image_width``, ``image_height``, ``camera_matrix``, ``distortion_coefficients``,
    ``rvec`` (``rotation="rvec"``) or ``rotation_matrix`` (``rotation="matrix"``), ``tvec``
    (metres divided by ``unit``, e.g. unit=0.001 writes millimetres). Written atomically
    (:func:`silpose.shared.atomic.atomic_path`; the format is passed explicitly because the
    temporary name does not end in the final suffix).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".xml", ".yml", ".yaml"):
        raise RigError(f"{path}: OpenCV calibration files must end in .xml, .yml or .yaml")
    if rotation not in ("rvec", "matrix"):
        raise ValueError(f"rotation must be 'rvec' or 'matrix', got {rotation!r}")
    if not (np.isfinite(unit) and unit > 0):
        raise ValueError(f"unit must be a positive number, got {unit}")
    fmt = cv2.FILE_STORAGE_FORMAT_XML if suffix == ".xml" else cv2.FILE_STORAGE_FORMAT_YAML
    with atomic_path(path) as tmp:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE | fmt)
        try:
            fs.write("name", camera.name)
            fs.write("image_width", int(camera.width))
            fs.write("image_height", int(camera.height))
            fs.write("camera_matrix", np.asarray(camera.K, np.float64))
            fs.write("distortion_coefficients", np.asarray(camera.dist, np.float64).reshape(-1, 1))
            if rotation == "rvec":
                fs.write("rvec", rotation_to_rvec(camera.R).reshape(3, 1))
            else:
                fs.write("rotation_matrix", np.asarray(camera.R, np.float64))
            fs.write("tvec", (np.asarray(camera.t, np.float64) / unit).reshape(3, 1))
        finally:
            fs.release()
