"""COLMAP sparse models: ``cameras.txt`` + ``images.txt``, or ``cameras.bin`` + ``images.bin`` (``sparse/0/``).

A lab that calibrates its fixed rig by structure from motion has a COLMAP model. silpose reads two of its
files, found side by side (give either; both are read once, ``rigs``/``frames``/``points3D`` are not needed):

``cameras.txt``: ``#`` comment lines, then one line per camera ``CAMERA_ID MODEL WIDTH HEIGHT PARAMS...``.
The models silpose reads, with their parameters and the OpenCV distortion they become:

==================  ==========================================  ================================
model               params                                      OpenCV ``dist``
==================  ==========================================  ================================
``SIMPLE_PINHOLE``  ``f cx cy``                                 none
``PINHOLE``         ``fx fy cx cy``                             none
``SIMPLE_RADIAL``   ``f cx cy k``                               ``k 0 0 0 0``
``RADIAL``          ``f cx cy k1 k2``                           ``k1 k2 0 0 0``
``OPENCV``          ``fx fy cx cy k1 k2 p1 p2``                 ``k1 k2 p1 p2 0``
``FULL_OPENCV``     ``fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6``     ``k1 k2 p1 p2 k3 k4 k5 k6``
``OPENCV_FISHEYE``  ``fx fy cx cy k1 k2 k3 k4``                 fisheye ``k1 k2 k3 k4``
==================  ==========================================  ================================

(COLMAP's ``src/colmap/sensor/models.h`` applies the same polynomials as OpenCV, FULL_OPENCV being OpenCV's
rational model, OPENCV_FISHEYE OpenCV's fisheye model: a camera with ``fisheye`` set.) Other models (``FOV``,
``THIN_PRISM_FISHEYE``, ``SIMPLE_FISHEYE``, ...) are refused: undistort first (``colmap image_undistorter``
writes a PINHOLE model) or reconstruct with OPENCV or OPENCV_FISHEYE.

**Principal point.** COLMAP puts the image's top-left *corner* at (0, 0), so the centre of the top-left pixel
is (0.5, 0.5) and a centred principal point is (W/2, H/2) (``models.h``; ``doc/faq.rst``: "cx_colmap =
cx_opencv + 0.5"). silpose, like OpenCV, puts pixel centres at whole numbers (docs/conventions.md), so it
reads ``cx - 0.5``, ``cy - 0.5``; :func:`write_colmap` adds the 0.5 back.

``images.txt``: two lines per registered image, ``IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME``, then its
keypoints ``X Y POINT3D_ID ...`` (a line that may be empty; it is also accepted missing). The unit
quaternion (Hamilton, scalar first) and ``T`` map the model's world to the camera, ``x_cam = R(q) X + T``
(camera x right, y down, z forward, as silpose's).

Binary (little-endian, as COLMAP's ``scene/reconstruction_io_binary.cc`` and
``scripts/python/read_write_model.py``): ``cameras.bin`` = uint64 count, then per camera uint32 id, int32
model id, uint64 width, uint64 height, the model's float64 params; ``images.bin`` = uint64 count, then per
image uint32 id, 4 float64 q, 3 float64 T, uint32 camera id, the NUL-terminated name, uint64 n, n x (float64
x, float64 y, uint64 point3D id).

**Cameras.** One silpose camera per registered image, in IMAGE_ID order, named after the image's folder when
the images lie in several folders (``cam01/frame0001.jpg`` -> ``cam01``), else after the file's stem.
Several images of one name (frames of one fixed camera) must share its intrinsics (one CAMERA_ID or equal
parameters) and agree on its pose (rotation within :data:`MAX_FRAME_ROTATION_DEG`, centre within
:data:`MAX_FRAME_SHIFT` of the cameras' spread); the camera is then read once, with its first image's pose.
A camera that moved is an error: silpose needs fixed cameras.

**Frame.** An SfM model's length unit and floor are arbitrary unless it was aligned (``colmap
model_aligner``); :func:`read_colmap` adds a note saying what to pass (``--unit``, ``--up``,
``--floor-offset``). Every problem is a one-line :class:`~silpose.shared.camera.RigError` naming the file,
the camera or image, and the line or record.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np

from silpose.shared.atomic import write_bytes_atomic, write_text_atomic
from silpose.shared.camera import RigError

from .calibration import CalibratedCamera, as_pixels, camera_matrix, rotation_from_values

__all__ = ["NAMES", "MODELS", "MAX_FRAME_ROTATION_DEG", "MAX_FRAME_SHIFT", "is_colmap", "colmap_pair",
           "read_colmap", "write_colmap"]

#: The file names of the two files silpose reads (any case), text and binary.
NAMES = ("cameras.txt", "images.txt", "cameras.bin", "images.bin")

#: COLMAP model id -> (name, number of params), as in ``src/colmap/sensor/models.h`` (ids 0-17).
MODELS: dict[int, tuple[str, int]] = {
    0: ("SIMPLE_PINHOLE", 3), 1: ("PINHOLE", 4), 2: ("SIMPLE_RADIAL", 4), 3: ("RADIAL", 5), 4: ("OPENCV", 8),
    5: ("OPENCV_FISHEYE", 8), 6: ("FULL_OPENCV", 12), 7: ("FOV", 5), 8: ("SIMPLE_RADIAL_FISHEYE", 4),
    9: ("RADIAL_FISHEYE", 5), 10: ("THIN_PRISM_FISHEYE", 12), 11: ("RAD_TAN_THIN_PRISM_FISHEYE", 16),
    12: ("SIMPLE_DIVISION", 4), 13: ("DIVISION", 5), 14: ("SIMPLE_FISHEYE", 3), 15: ("FISHEYE", 4),
    16: ("EUCM", 6), 17: ("EQUIRECTANGULAR", 2),
}
_NUM_PARAMS = {name: n for name, n in MODELS.values()}
_MODEL_IDS = {name: i for i, (name, _) in MODELS.items()}
#: The models silpose reads -> their parameter names.
_READ = {"SIMPLE_PINHOLE": "f cx cy", "PINHOLE": "fx fy cx cy", "SIMPLE_RADIAL": "f cx cy k",
         "RADIAL": "f cx cy k1 k2", "OPENCV": "fx fy cx cy k1 k2 p1 p2",
         "FULL_OPENCV": "fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6", "OPENCV_FISHEYE": "fx fy cx cy k1 k2 k3 k4"}
#: Frames of one camera agree when their rotations differ by at most this (degrees) ...
MAX_FRAME_ROTATION_DEG = 0.1
#: ... and their centres by at most this fraction of the cameras' spread (the diagonal of their bounding box).
MAX_FRAME_SHIFT = 1e-3


@dataclass(frozen=True)
class _Camera:
    id: int
    model: str
    width: int
    height: int
    params: np.ndarray
    where: str  # "line 4" / "camera record 2"


@dataclass(frozen=True)
class _Image:
    id: int
    q: np.ndarray  # w, x, y, z
    t: np.ndarray
    camera_id: int
    name: str
    where: str


def is_colmap(path: str | Path) -> bool:
    """True for a file named ``cameras.txt``, ``images.txt``, ``cameras.bin`` or ``images.bin`` (any case)."""
    return Path(path).name.lower() in NAMES


def _sibling(path: Path, name: str) -> Path:
    """``name`` next to ``path``, matched case-insensitively when the exact spelling is absent."""
    exact = path.with_name(name)
    if exact.is_file() or not path.parent.is_dir():
        return exact
    return next((q for q in sorted(path.parent.iterdir()) if q.name.lower() == name and q.is_file()), exact)


def colmap_pair(path: str | Path) -> tuple[Path, Path]:
    """(cameras, images) of the model ``path`` belongs to: the other file is looked for next to it, with the
    same suffix (``.txt`` or ``.bin``)."""
    p = Path(path)
    name = p.name.lower()
    if name not in NAMES:
        raise RigError(f"{p}: a COLMAP model is cameras.txt + images.txt (or cameras.bin + images.bin) in one folder")
    kind, suffix = name.split(".")
    other = _sibling(p, ("images." if kind == "cameras" else "cameras.") + suffix)
    return (p, other) if kind == "cameras" else (other, p)


# ----------------------------------------------------------------------------------------------- text


def _lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise RigError(f"{path}: cannot read this file as text ({exc})") from None


def _int(word: str, where: str, what: str) -> int:
    try:
        return int(word)
    except ValueError:
        raise RigError(f"{where}: {what}: expected a whole number, got {word!r}") from None


def _floats(words: list[str], where: str, what: str) -> np.ndarray:
    try:
        v = np.array([float(w) for w in words], dtype=np.float64)
    except ValueError:
        raise RigError(f"{where}: {what}: expected numbers, got {' '.join(words)!r}") from None
    if not np.all(np.isfinite(v)):
        raise RigError(f"{where}: {what}: contains NaN or infinity")
    return v


def _check_count(source: str, cam: _Camera) -> None:
    n = _NUM_PARAMS.get(cam.model)
    if n is not None and cam.params.size != n:
        names = f" ({_READ[cam.model]})" if cam.model in _READ else ""
        raise RigError(f"{source}: {cam.where}: camera {cam.id}: model {cam.model} has {n} parameters{names}, "
                       f"got {cam.params.size}")


def _read_cameras_text(path: Path) -> dict[int, _Camera]:
    source = str(path)
    cams: dict[int, _Camera] = {}
    for number, line in enumerate(_lines(path), start=1):
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        where = f"{source}: line {number}"
        if len(words) < 4:
            raise RigError(f"{where}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS..., got {line.strip()!r}")
        cid = _int(words[0], where, "CAMERA_ID")
        size = _floats(words[2:4], where, f"camera {cid}: WIDTH HEIGHT")
        width = as_pixels(size[0], f"{where}: camera {cid}: WIDTH")
        height = as_pixels(size[1], f"{where}: camera {cid}: HEIGHT")
        cam = _Camera(cid, words[1].upper(), width, height, _floats(words[4:], where, f"camera {cid}: PARAMS"),
                      f"line {number}")
        _check_count(source, cam)
        if cid in cams:
            raise RigError(f"{where}: CAMERA_ID {cid} is also the camera of {cams[cid].where}")
        cams[cid] = cam
    return cams


def _is_points_line(words: list[str]) -> bool:
    """True for an images.txt keypoint line ``X Y POINT3D_ID ...`` (an image line has 10 fields)."""
    if len(words) % 3:
        return False
    try:
        for w in words:
            float(w)
    except ValueError:
        return False
    return True


def _read_images_text(path: Path) -> list[_Image]:
    source = str(path)
    images: list[_Image] = []
    after_image = False
    for number, line in enumerate(_lines(path), start=1):
        words = line.split()
        if after_image:  # the image's keypoint line: empty, X Y POINT3D_ID triples, or left out
            after_image = False
            if not words or _is_points_line(words):
                continue
        if not words or words[0].startswith("#"):
            continue
        where = f"{source}: line {number}"
        if len(words) < 10:
            raise RigError(f"{where}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, got "
                           f"{len(words)} fields")
        iid = _int(words[0], where, "IMAGE_ID")
        name = " ".join(words[9:])
        pose = _floats(words[1:8], where, f"image {name!r}: QW QX QY QZ TX TY TZ")
        images.append(_Image(iid, pose[:4], pose[4:], _int(words[8], where, f"image {name!r}: CAMERA_ID"), name,
                             f"line {number}"))
        after_image = True
    return images


# --------------------------------------------------------------------------------------------- binary


class _Bytes:
    """A cursor over a little-endian file's bytes; reading past the end is a one-line error."""

    def __init__(self, path: Path):
        self.source = str(path)
        try:
            self.data = path.read_bytes()
        except OSError as exc:
            raise RigError(f"{path}: cannot read this file ({exc.strerror or exc})") from None
        self.pos = 0

    def take(self, fmt: str, what: str) -> tuple:
        size = struct.calcsize("<" + fmt)
        if self.pos + size > len(self.data):
            raise RigError(f"{self.source}: truncated: {what} runs past the end of the file (byte {self.pos} of "
                           f"{len(self.data)}); not a complete COLMAP model file")
        out = struct.unpack_from("<" + fmt, self.data, self.pos)
        self.pos += size
        return out

    def count(self, item_bytes: int, what: str) -> int:
        """A uint64 count of items of at least ``item_bytes`` bytes each, checked against the bytes left."""
        (n,) = self.take("Q", f"the number of {what}")
        if n * item_bytes > len(self.data) - self.pos:
            raise RigError(f"{self.source}: truncated: {n} {what} need at least {n * item_bytes} bytes, "
                           f"{len(self.data) - self.pos} remain (byte {self.pos})")
        return n

    def name(self, what: str) -> str:
        end = self.data.find(b"\0", self.pos)
        if end < 0:
            raise RigError(f"{self.source}: truncated: {what} has no terminating NUL byte (byte {self.pos})")
        raw = self.data[self.pos:end]
        self.pos = end + 1
        return raw.decode("utf-8", errors="replace")

    def done(self, what: str) -> None:
        if self.pos != len(self.data):
            raise RigError(f"{self.source}: {len(self.data) - self.pos} bytes after the last {what}: not a COLMAP "
                           "model file, or cameras.bin and images.bin swapped?")


def _read_cameras_binary(path: Path) -> dict[int, _Camera]:
    b = _Bytes(path)
    cams: dict[int, _Camera] = {}
    for i in range(b.count(24, "cameras")):
        what = f"camera record {i + 1}"
        cid, model_id, width, height = b.take("IiQQ", what)
        if model_id not in MODELS:
            raise RigError(f"{b.source}: {what}: camera {cid}: unknown camera model id {model_id} (silpose knows "
                           f"0-{max(MODELS)}); export the model as text (colmap model_converter --output_type TXT)")
        model, n = MODELS[model_id]
        params = np.array(b.take("d" * n, f"{what} (camera {cid}, {model})"), dtype=np.float64)
        if not np.all(np.isfinite(params)):
            raise RigError(f"{b.source}: {what}: camera {cid}: params contain NaN or infinity")
        w = as_pixels(float(width), f"{b.source}: {what}: camera {cid}: width")
        h = as_pixels(float(height), f"{b.source}: {what}: camera {cid}: height")
        if cid in cams:
            raise RigError(f"{b.source}: {what}: CAMERA_ID {cid} is also the camera of {cams[cid].where}")
        cams[cid] = _Camera(cid, model, w, h, params, what)
    b.done("camera")
    return cams


def _read_images_binary(path: Path) -> list[_Image]:
    b = _Bytes(path)
    images: list[_Image] = []
    for i in range(b.count(73, "images")):  # 64 bytes of id, pose and camera, a NUL, a uint64 count
        what = f"image record {i + 1}"
        iid, *pose, cid = b.take("I7dI", what)
        name = b.name(f"{what} (IMAGE_ID {iid}): its name")
        (n,) = b.take("Q", f"{what} ({name!r}): its number of keypoints")
        if n * 24 > len(b.data) - b.pos:
            raise RigError(f"{b.source}: truncated: {what} ({name!r}) has {n} keypoints, which need {n * 24} bytes; "
                           f"{len(b.data) - b.pos} remain (byte {b.pos})")
        b.pos += 24 * n
        v = np.array(pose, dtype=np.float64)
        if not np.all(np.isfinite(v)):
            raise RigError(f"{b.source}: {what}: image {name!r}: pose contains NaN or infinity")
        images.append(_Image(iid, v[:4], v[4:], cid, name, what))
    b.done("image")
    return images


# ------------------------------------------------------------------------------------------ cameras


def _rotation(q: np.ndarray, where: str) -> np.ndarray:
    """The rotation of a unit quaternion (w, x, y, z), Hamilton convention."""
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > 1e-3:
        raise RigError(f"{where}: QW QX QY QZ is not a unit quaternion (norm {norm:.6g})")
    w, x, y, z = q / norm
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return rotation_from_values(R.ravel(), where)


def _quaternion(R: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of a rotation matrix, w >= 0 (the largest of the four squares picks the stable formula)."""
    R = np.asarray(R, dtype=np.float64)
    squares = 1.0 + np.array([R[0, 0] + R[1, 1] + R[2, 2], R[0, 0] - R[1, 1] - R[2, 2],
                              -R[0, 0] + R[1, 1] - R[2, 2], -R[0, 0] - R[1, 1] + R[2, 2]])
    k = int(np.argmax(squares))
    s = 2.0 * np.sqrt(squares[k])  # = 4 * |q_k|
    if k == 0:
        q = [s / 4, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif k == 1:
        q = [(R[2, 1] - R[1, 2]) / s, s / 4, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif k == 2:
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, s / 4, (R[1, 2] + R[2, 1]) / s]
    else:
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, s / 4]
    q = np.array(q)
    return -q if q[0] < 0 else q


def _intrinsics(cam: _Camera, source: str, image: str) -> tuple[np.ndarray, np.ndarray]:
    """(K with silpose's principal point, OpenCV dist -- the fisheye model's 4 coefficients for OPENCV_FISHEYE) of a
    model silpose reads; the refusal otherwise."""
    where = f"{source}: {cam.where}: camera {cam.id}"
    if cam.model not in _READ:
        kind = "a non-OpenCV" if cam.model in _NUM_PARAMS else "an unknown"
        raise RigError(f"{where} (of image {image!r}): model {cam.model} is {kind} camera model; silpose reads "
                       f"{', '.join(_READ)}: undistort the images first (colmap image_undistorter writes a PINHOLE "
                       "model) or reconstruct again with the OPENCV, OPENCV_FISHEYE or PINHOLE camera model")
    p = cam.params
    if cam.model in ("SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL"):
        fx = fy = p[0]
        cx, cy, extra = p[1], p[2], p[3:]
    else:
        fx, fy, cx, cy, extra = p[0], p[1], p[2], p[3], p[4:]
    K = camera_matrix(np.array([[fx, 0.0, cx - 0.5], [0.0, fy, cy - 0.5], [0.0, 0.0, 1.0]]), f"{where}: PARAMS")
    if cam.model in ("FULL_OPENCV", "OPENCV_FISHEYE"):
        return K, extra.copy()
    dist = np.zeros(5)
    dist[:extra.size] = extra  # k | k1 k2 | k1 k2 p1 p2
    return K, dist


def _camera_names(images: list[_Image]) -> tuple[list[str], bool]:
    """Per image: its folder's name when the images lie in several folders, else its file's stem."""
    paths = [PurePosixPath(im.name.replace("\\", "/")) for im in images]
    folders = [p.parent for p in paths]
    distinct = sorted(set(folders), key=folders.index)
    if len(distinct) > 1 and all(str(f) != "." for f in folders):
        last = {f: f.name for f in distinct}
        by_last = len(set(last.values())) == len(distinct)
        return [last[f] if by_last else str(f) for f in folders], True
    return [p.stem for p in paths], False


def _angle_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(Ra @ Rb.T) - 1.0) / 2.0, -1.0, 1.0))))


def read_colmap(path: str | Path, notes: list[str] | None = None) -> list[CalibratedCamera]:
    """The cameras of the COLMAP model ``path`` belongs to (module docstring), one per fixed camera; what was
    decided is appended to ``notes``."""
    cameras_path, images_path = colmap_pair(path)
    for p in (cameras_path, images_path):
        if not p.is_file():
            raise RigError(f"{p}: not found (a COLMAP model is cameras.txt + images.txt, or cameras.bin + "
                           "images.bin, side by side)")
    binary = cameras_path.suffix.lower() == ".bin"
    cams = _read_cameras_binary(cameras_path) if binary else _read_cameras_text(cameras_path)
    images = _read_images_binary(images_path) if binary else _read_images_text(images_path)
    c_src, i_src = str(cameras_path), str(images_path)
    if not images:
        raise RigError(f"{i_src}: no registered image (an empty model)")
    seen: dict[int, _Image] = {}
    for im in images:
        if im.id in seen:
            raise RigError(f"{i_src}: {im.where}: IMAGE_ID {im.id} is also the image of {seen[im.id].where}")
        seen[im.id] = im
        if im.camera_id not in cams:
            raise RigError(f"{i_src}: {im.where}: image {im.name!r}: CAMERA_ID {im.camera_id} is not a camera of "
                           f"{c_src}")
    images = sorted(images, key=lambda im: im.id)
    names, by_folder = _camera_names(images)
    poses = [(_rotation(im.q, f"{i_src}: {im.where}: image {im.name!r}"), im.t) for im in images]
    centres = np.array([-R.T @ t for R, t in poses])
    groups: dict[str, list[int]] = {}
    for i, n in enumerate(names):
        groups.setdefault(n, []).append(i)
    firsts = centres[[g[0] for g in groups.values()]]
    spread = float(np.linalg.norm(firsts.max(axis=0) - firsts.min(axis=0)))
    if spread == 0.0:  # one camera: compare with the model's size (or one unit)
        spread = float(np.linalg.norm(centres, axis=1).max()) or 1.0
    out = []
    for name, members in groups.items():
        first = images[members[0]]
        cam = cams[first.camera_id]
        K, dist = _intrinsics(cam, c_src, first.name)
        R, t = poses[members[0]]
        for j in members[1:]:
            other = images[j]
            ocam = cams[other.camera_id]
            if other.camera_id != first.camera_id:
                K2, dist2 = _intrinsics(ocam, c_src, other.name)
                if ((ocam.width, ocam.height) != (cam.width, cam.height) or dist2.shape != dist.shape
                        or not np.allclose(K2, K, rtol=1e-9, atol=0) or not np.allclose(dist2, dist, rtol=1e-9,
                                                                                        atol=1e-12)):
                    raise RigError(
                        f"{i_src}: {other.where}: image {other.name!r} of camera {name!r} has other intrinsics "
                        f"(CAMERA_ID {other.camera_id}) than image {first.name!r} (CAMERA_ID {first.camera_id}): "
                        "silpose needs one calibration per camera (extract features with "
                        "--ImageReader.single_camera_per_folder 1)")
            angle = _angle_deg(poses[j][0], R)
            shift = float(np.linalg.norm(centres[j] - centres[members[0]]))
            if angle > MAX_FRAME_ROTATION_DEG or shift > MAX_FRAME_SHIFT * spread:
                raise RigError(
                    f"{i_src}: {other.where}: image {other.name!r} of camera {name!r} is {angle:.3g} deg and "
                    f"{shift:.3g} model units away from image {first.name!r}: the camera moved; silpose needs fixed "
                    "cameras (keep one image per camera, or name each image's camera by its folder)")
        out.append(CalibratedCamera(name=name, K=K, dist=dist, R=R, t=np.asarray(t, dtype=np.float64).copy(),
                                    size=(cam.width, cam.height), source=i_src, where=f"{name}.",
                                    fisheye=cam.model == "OPENCV_FISHEYE"))
    if notes is not None:
        if by_folder:
            notes.append(f"{i_src}: cameras named after their images' folders")
        several = [(n, len(m)) for n, m in groups.items() if len(m) > 1]
        if several:
            listed = ", ".join(f"{n} ({k})" for n, k in several[:6]) + (" ..." if len(several) > 6 else "")
            notes.append(f"{i_src}: {len(images)} images of {len(groups)} fixed camera(s), several frames each "
                         f"({listed}): their poses agree (within {MAX_FRAME_ROTATION_DEG:g} deg and "
                         f"{MAX_FRAME_SHIFT:g} of the cameras' spread), so each camera is read once, with its "
                         "first image's pose")
        notes.append(f"{i_src}: an SfM model's unit and floor are arbitrary unless it was aligned (colmap "
                     "model_aligner): silpose reads one model unit as one metre unless --unit says how many "
                     "metres it is, takes up from the cameras' image up (--up to set it) and the floor as the "
                     "model's plane through its origin (--floor-offset: the floor's coordinate along up, in model "
                     "units); check the camera heights below")
    return out


# ----------------------------------------------------------------------------------------------- writer


def _colmap_params(c: CalibratedCamera) -> tuple[str, list[float]]:
    K = np.asarray(c.K, dtype=np.float64)
    if K[0, 1] != 0:
        raise ValueError(f"camera {c.name!r}: COLMAP models have no skew")
    d = np.asarray(c.dist, dtype=np.float64).ravel()
    pinhole = [K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5]
    if c.fisheye:
        return "OPENCV_FISHEYE", pinhole + list(d[:4])
    if d.size > 8 and np.any(d[8:] != 0):
        raise ValueError(f"camera {c.name!r}: COLMAP has no thin-prism or tilt terms (OpenCV dist beyond k6)")
    full = np.zeros(8)
    full[:min(d.size, 8)] = d[:8]
    if not np.any(full):
        return "PINHOLE", pinhole
    if not np.any(full[4:]):
        return "OPENCV", pinhole + list(full[:4])
    return "FULL_OPENCV", pinhole + list(full)


def write_colmap(folder: str | Path, cameras: list[CalibratedCamera], binary: bool = False,
                 frames: int = 1) -> tuple[Path, Path]:
    """Write ``cameras`` as a COLMAP model in ``folder`` (tests and examples): ``cameras`` + ``images``, text or
    binary. One COLMAP camera per camera (PINHOLE without distortion, OPENCV, FULL_OPENCV when k3..k6 are
    used, OPENCV_FISHEYE for a fisheye lens; ``cx``, ``cy`` + 0.5); its image ``<name>.jpg``, or with ``frames`` > 1 that many images
    ``<name>/frame0001.jpg`` ... with the same pose. Returns (cameras, images)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cam_rows, image_rows = [], []
    for i, c in enumerate(cameras, start=1):
        if c.size is None:
            raise ValueError(f"camera {c.name!r} has no image size")
        model, params = _colmap_params(c)
        cam_rows.append((i, model, int(c.size[0]), int(c.size[1]), [float(x) for x in params]))
        q, t = _quaternion(c.R), np.asarray(c.t, dtype=np.float64).ravel()
        for j in range(1, frames + 1):
            name = f"{c.name}.jpg" if frames == 1 else f"{c.name}/frame{j:04d}.jpg"
            image_rows.append((len(image_rows) + 1, [float(x) for x in q], [float(x) for x in t], i, name))
    if binary:
        cam_bytes = struct.pack("<Q", len(cam_rows)) + b"".join(
            struct.pack(f"<IiQQ{len(p)}d", cid, _MODEL_IDS[m], w, h, *p) for cid, m, w, h, p in cam_rows)
        img_bytes = struct.pack("<Q", len(image_rows)) + b"".join(
            struct.pack("<I7dI", iid, *q, *t, cid) + name.encode("utf-8") + b"\0" + struct.pack("<Q", 0)
            for iid, q, t, cid, name in image_rows)
        return (write_bytes_atomic(folder / "cameras.bin", cam_bytes),
                write_bytes_atomic(folder / "images.bin", img_bytes))
    cam_text = ["# Camera list with one line of data per camera:", "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
                f"# Number of cameras: {len(cam_rows)}"]
    cam_text += [" ".join([str(cid), m, str(w), str(h)] + [repr(x) for x in p]) for cid, m, w, h, p in cam_rows]
    img_text = ["# Image list with two lines of data per image:",
                "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME", "#   POINTS2D[] as (X, Y, POINT3D_ID)",
                f"# Number of images: {len(image_rows)}, mean observations per image: 0"]
    for iid, q, t, cid, name in image_rows:
        img_text += [" ".join([str(iid)] + [repr(x) for x in q + t] + [str(cid), name]), ""]
    return (write_text_atomic(folder / "cameras.txt", "\n".join(cam_text) + "\n"),
            write_text_atomic(folder / "images.txt", "\n".join(img_text) + "\n"))
