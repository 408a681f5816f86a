"""One camera as a calibration file states it, before silpose's frame is applied.

Every format reader (:mod:`.opencv`, :mod:`.easymocap`, :mod:`.pose2sim`) produces
:class:`CalibratedCamera` records: intrinsics in pixels and the world->camera pose in the
calibration's own world frame and length unit. :mod:`.importer` turns them into a silpose
:class:`~silpose.shared.camera.Rig` through a :class:`~silpose.shared.rig_frame.WorldTransform`.

Fields are looked up by *spelling-insensitive* names (:data:`FIELD_ALIASES`): a key matches when it
equals an alias after lower-casing and dropping everything but letters and digits, so
``camera_matrix``, ``cameraMatrix`` and ``CameraMatrix`` are one name; a leading ``camera`` and endings such as
``Vecs`` or ``Values`` are read through too (:func:`key_forms`: ``CameraRotationVecs``, ``TranslationValues``,
``CameraIntrinsicMatrix`` -- spellings of course and lab calibration scripts). A rotation is a Rodrigues
vector (3 values) or a 3x3 matrix, told apart by its size; several keys naming the same field must
agree. Every problem is a :class:`~silpose.shared.camera.RigError` whose one-line message names the
file and the field.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable

import cv2
import numpy as np

from silpose.shared.camera import RigError

__all__ = [
    "CalibratedCamera",
    "FIELD_ALIASES",
    "FieldReader",
    "normalise_key",
    "key_forms",
    "rotation_from_values",
    "rotation_to_rvec",
    "as_pixels",
    "camera_matrix",
    "distortion",
]

#: field -> accepted key spellings, normalised (:func:`normalise_key`). The first group of the
#: issue's list plus the common variants of OpenCV's samples, calibrateCamera wrappers, EasyMocap
#: (after its ``_<name>`` suffix is removed) and Pose2Sim/anipose.
FIELD_ALIASES: dict[str, tuple[str, ...]] = {
    "camera matrix": ("cameramatrix", "k", "m", "intrinsic", "intrinsics", "intrinsicmatrix", "matrix", "mtx",
                      "kmatrix", "cameraintrinsics", "calibrationmatrix"),
    "distortion": ("distortioncoefficients", "distortioncoeffs", "distcoeffs", "distcoeff", "distcoefs", "distcoef", "dist",
                   "d", "distortion", "distortions"),
    "rotation": ("rotationvector", "rotationvectors", "rvec", "rvecs", "rvector", "rotation", "r", "rot",
                 "rotationmatrix", "rmat", "rotmatrix", "rotmat", "extrinsicr"),
    "translation": ("translationvector", "translationvectors", "tvec", "tvecs", "tvector", "translation", "t",
                    "extrinsict"),
    "image size": ("imagesize", "size", "resolution"),
    "image width": ("imagewidth", "width", "w", "framewidth"),
    "image height": ("imageheight", "height", "h", "frameheight"),
    "name": ("name", "cameraname"),
}
_DIST_SIZES = (4, 5, 8, 12, 14)


def normalise_key(key: str) -> str:
    """``"Camera_Matrix"`` -> ``"cameramatrix"``: lower case, letters and digits only."""
    return re.sub(r"[^a-z0-9]", "", str(key).lower())


#: word endings people use for the same thing, read as the alias spelling (``RotationVecs``, ``TranslationValues``)
_ENDINGS = (("vecs", "vector"), ("vec", "vector"), ("values", "vector"), ("vals", "vector"), ("mat", "matrix"))


def key_forms(base: str) -> set[str]:
    """The spellings a normalised key is read as: itself, without a leading ``camera`` (``CameraRotationVecs``,
    ``CameraIntrinsicMatrix``), and each of those with a common ending replaced (:data:`_ENDINGS`)."""
    forms = {base}
    if base.startswith("camera") and len(base) > len("camera"):
        forms.add(base[len("camera"):])
    for f in list(forms):
        for end, canonical in _ENDINGS:
            if f.endswith(end) and len(f) > len(end):
                forms.add(f[: -len(end)] + canonical)
    return forms


@dataclass(frozen=True, eq=False)
class CalibratedCamera:
    """One camera in its calibration's frame and units.

    Attributes:
        name: the camera's name (from the file, its section, or the file stem).
        K: (3, 3) intrinsic matrix, pixels.
        dist: OpenCV distortion coefficients (4, 5, 8, 12 or 14 values).
        R: (3, 3) world->camera rotation in the calibration's world frame.
        t: (3,) world->camera translation in calibration units.
        size: (width, height) pixels, or None when the file does not say.
        source: the file it came from; ``where`` prefixes field names in errors (e.g. ``cam_01.``).
        group: the set of poses it belongs to when a file holds several per camera (Human3.6M's subjects
            ``S1`` ... in a JSON of intrinsics and per-subject extrinsics); None otherwise.
        fisheye: ``dist`` is OpenCV's fisheye model (k1, k2, k3, k4; :class:`silpose.shared.pinhole.Camera`).
    """

    name: str
    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    size: tuple[int, int] | None
    source: str
    where: str = ""
    group: str | None = None
    fisheye: bool = False

    def field_name(self, name: str) -> str:
        """``"<file>: field <where><name>"``, the start of an error about one of its fields."""
        return f"{self.source}: field {self.where}{name}"


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


def rotation_from_values(value: np.ndarray, where: str) -> np.ndarray:
    """A (3, 3) rotation from a Rodrigues vector (3 values) or a matrix (9 values); ``where`` names
    the field in errors (``"<file>: field <key>"``)."""
    v = np.asarray(value, dtype=np.float64)
    if v.size == 3:
        return cv2.Rodrigues(v.reshape(3, 1))[0]
    if v.size == 9:
        R = v.reshape(3, 3)
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0:
            raise RigError(f"{where}: not a rotation matrix (R R^T != I or det(R) != +1)")
        return R
    if v.size % 3 == 0 and v.ndim == 2 and 3 in v.shape:
        n = v.size // 3
        raise RigError(
            f"{where}: {n} rotation vectors (one per calibration image?); silpose needs this camera's one pose "
            "in the world frame: a Rodrigues vector (3 values) or a 3x3 matrix"
        )
    hint = " (a quaternion? silpose reads Rodrigues vectors and rotation matrices)" if v.size == 4 else ""
    raise RigError(f"{where}: expected 3 values (Rodrigues vector) or 3x3 (rotation matrix), got shape {v.shape}{hint}")


def as_pixels(value: float, where: str) -> int:
    """A positive whole number of pixels (``1088.0`` is fine, ``1088.5`` is not)."""
    if not np.isfinite(value) or value != np.round(value) or value <= 0:
        raise RigError(f"{where}: expected a positive whole number of pixels, got {value}")
    return int(value)


class FieldReader:
    """The named values of one camera's record, looked up by :data:`FIELD_ALIASES`.

    Args:
        keys: the record's keys, as written in the file (order kept).
        get: key -> a float numpy array, a string, or None (a value that is neither).
        source: the file; ``where`` prefixes key names in errors (e.g. ``"cam_01."``).
        suffix: a per-camera key suffix stripped before matching (EasyMocap's ``_<name>``).
        source_of: key -> the file holding it, when the record spans several files.
    """

    def __init__(self, keys, get: Callable[[str], object], source: str, where: str = "", suffix: str = "",
                 source_of: Callable[[str], str] | None = None):
        self.keys = [str(k) for k in keys]
        self.get = get
        self.source = source
        self.where = where
        self.suffix = suffix
        self.source_of = source_of

    def field(self, key: str) -> str:
        return f"{self.source_of(key) if self.source_of else self.source}: field {self.where}{key}"

    def _base(self, key: str) -> str | None:
        """The key without the per-camera suffix, normalised (None: another camera's key)."""
        if self.suffix:
            return normalise_key(key[: -len(self.suffix)]) if key.endswith(self.suffix) else None
        return normalise_key(key)

    def _spells(self, key: str, name: str) -> bool:
        base = self._base(key)
        return base is not None and any(form in FIELD_ALIASES[name] for form in key_forms(base))

    def matches(self, name: str) -> list[str]:
        """The record's keys spelling field ``name`` (in file order)."""
        return [k for k in self.keys if self._spells(k, name)]

    def unused_keys(self) -> list[str]:
        """Keys that spell no field silpose reads (listed when a required field is missing)."""
        return [k for k in self.keys if self._base(k) is not None and not any(self._spells(k, n) for n in FIELD_ALIASES)]

    def missing(self, name: str) -> RigError:
        """The error for a missing required field: what we looked for and what the record has."""
        spellings = ", ".join(FIELD_ALIASES[name])
        unused = self.unused_keys()
        seen = f"; keys silpose does not read here: {', '.join(unused)}" if unused else ""
        return RigError(
            f"{self.source}: missing field {self.where}{name} (any case or underscores of: {spellings}){seen}"
        )

    def numbers(self, name: str, required: bool = True) -> list[tuple[str, np.ndarray]]:
        """Every ``(key, finite float array)`` spelling field ``name``; [] if absent and not required."""
        keys = self.matches(name)
        if not keys:
            if required:
                raise self.missing(name)
            return []
        out = []
        for k in keys:
            v = self.get(k)
            if v is None or isinstance(v, str):
                raise RigError(f"{self.field(k)}: expected numbers")
            v = np.asarray(v, dtype=np.float64)
            if v.size == 0:
                raise RigError(f"{self.field(k)}: empty")
            if not np.all(np.isfinite(v)):
                raise RigError(f"{self.field(k)}: contains NaN or infinity")
            out.append((k, v))
        return out

    def agreed(self, name: str, values: list[tuple[str, np.ndarray]], convert, atol: float):
        """``convert(value, where)`` of every spelling; they must agree within ``atol``."""
        first_key, first = values[0][0], convert(values[0][1], self.field(values[0][0]))
        for k, v in values[1:]:
            other = convert(v, self.field(k))
            if np.shape(other) != np.shape(first) or not np.allclose(other, first, atol=atol, rtol=0):
                raise RigError(f"{self.field(k)}: disagrees with field {self.where}{first_key} ({name})")
        return first_key, first

    def string(self, name: str) -> str | None:
        keys = self.matches(name)
        if not keys:
            return None
        v = self.get(keys[0])
        if isinstance(v, str):
            return v
        if isinstance(v, np.ndarray) and v.size == 1 and np.isfinite(v).all() and float(v) == round(float(v)):
            return str(int(v.ravel()[0]))  # a numeric name such as 1
        raise RigError(f"{self.field(keys[0])}: expected a string")

    def image_size(self) -> tuple[int, int] | None:
        """(width, height) from ``image_size``-like [w, h] or ``image_width`` + ``image_height``; None if absent."""
        sizes = self.numbers("image size", required=False)
        widths = self.numbers("image width", required=False)
        heights = self.numbers("image height", required=False)
        found = []
        for k, v in sizes:
            if v.size != 2:
                raise RigError(f"{self.field(k)}: expected [width, height], got shape {v.shape}")
            found.append((k, (as_pixels(v.ravel()[0], self.field(k) + " [width]"),
                              as_pixels(v.ravel()[1], self.field(k) + " [height]"))))
        if widths or heights:
            if not (widths and heights):
                k = (widths or heights)[0][0]
                raise RigError(f"{self.field(k)}: image width and height come together (the other is missing)")
            (kw, w), (kh, h) = widths[0], heights[0]
            if w.size != 1 or h.size != 1:
                raise RigError(f"{self.field(kw if w.size != 1 else kh)}: expected one number")
            found.append((f"{kw} + {kh}", (as_pixels(float(w.ravel()[0]), self.field(kw)),
                                           as_pixels(float(h.ravel()[0]), self.field(kh)))))
        if not found:
            return None
        for k, s in found[1:]:
            if s != found[0][1]:
                raise RigError(f"{self.field(k)}: image size {s[0]}x{s[1]} conflicts with field "
                               f"{self.where}{found[0][0]} ({found[0][1][0]}x{found[0][1][1]})")
        return found[0][1]

    def camera(self, default_name: str, require_pose: bool = True) -> CalibratedCamera:
        """The camera of this record (intrinsics, pose, size when present, name)."""
        _, K = self.agreed("camera matrix", self.numbers("camera matrix"), camera_matrix, 1e-9)
        dists = self.numbers("distortion", required=False)
        dist = self.agreed("distortion", dists, distortion, 1e-12)[1] if dists else np.zeros(5)
        _, R = self.agreed("rotation", self.numbers("rotation"), rotation_from_values, 1e-6)
        _, t = self.agreed("translation", self.numbers("translation"), _translation, 1e-9)
        size = self.image_size()
        name = self.string("name") or default_name
        return CalibratedCamera(name=name, K=K, dist=dist, R=R, t=t, size=size, source=self.source, where=self.where)


def camera_matrix(value: np.ndarray, where: str) -> np.ndarray:
    """A (3, 3) camera matrix from 9 values; RigError naming ``where`` otherwise."""
    if value.size != 9:
        raise RigError(f"{where}: expected a 3x3 camera matrix, got shape {value.shape}")
    K = value.reshape(3, 3)
    if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1], atol=1e-9):
        raise RigError(f"{where}: not a camera matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
    return K


def distortion(value: np.ndarray, where: str) -> np.ndarray:
    """OpenCV distortion coefficients (4, 5, 8, 12 or 14 values); RigError naming ``where`` otherwise."""
    d = value.ravel()
    if d.size not in _DIST_SIZES:
        raise RigError(f"{where}: expected 4, 5, 8, 12 or 14 distortion coefficients, got {d.size}")
    return d


def _translation(value: np.ndarray, where: str) -> np.ndarray:
    if value.size != 3:
        n = value.size // 3 if value.size % 3 == 0 else 0
        more = f" ({n} translation vectors, one per calibration image?)" if n > 1 else ""
        raise RigError(f"{where}: expected 3 values, got shape {value.shape}{more}")
    return value.ravel()
