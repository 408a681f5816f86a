"""Qualisys Track Manager calibrations: ``*.qca.txt`` / ``*.qca`` (the XML QTM exports; Pose2Sim's demos ship one).

An XML file whose ``calibration`` element (the root, or inside QTM's ``QTM_Parameters_Ver_*``) holds one
``cameras/camera`` element per camera::

    <camera active="1" serial="cam01" viewrotation="0" model="...">
      <fov_video left="0" top="0" right="1087" bottom="1919"/>     the video window, sensor pixels (inclusive)
      <transform x=".." y=".." z=".." r11=".." ... r33=".."/>     the camera's pose in the world, millimetres
      <intrinsic focalLengthU=".." focalLengthV=".." centerPointU=".." centerPointV=".."
                 radialDistortion1..3=".." tangentalDistortion1..2=".." skew=".."/>   sub-pixel units (1/64 px)
    </camera>

Conventions, as read here (checked on Pose2Sim's demo, whose cameras then look at the capture volume and
whose image "up" is the world's +z; ``docs/real-recordings.md``):

- ``x, y, z`` is the camera centre ``C`` in the world (millimetres: import with ``--unit mm``).
- The rows of ``M = [[r11, r12, r13], [r21, r22, r23], [r31, r32, r33]]`` are Qualisys' camera axes in the
  world, with the camera looking along its **−z** and its **+y** up in the image. OpenCV's camera looks along
  +z with y down, so the world -> camera rotation is ``R = diag(1, −1, −1) M`` and ``t = −R C``
  (``x_cam = R X + t``, docs/conventions.md "Cameras").
- Intrinsics are in sub-pixels of 1/64 px: ``fx = focalLengthU / 64``, ``cx = centerPointU / 64 − left``
  (likewise v with ``top``); ``skew`` is ignored when 0 and refused otherwise. The image is
  ``right − left + 1`` by ``bottom − top + 1`` pixels (``fov_video``).
- Distortion is OpenCV's ``k1, k2, p1, p2, k3`` = ``radialDistortion1, radialDistortion2,
  tangentalDistortion1, tangentalDistortion2, radialDistortion3`` as written (not scaled: on Pose2Sim's
  demo they agree with an independent ChArUco calibration of the same cameras).
- ``viewrotation`` only turns QTM's display; it is noted, not applied. Cameras with ``active="0"`` are
  left out (noted). Cameras are named by ``serial``, in file order.

Every problem is a one-line :class:`~silpose.shared.camera.RigError` naming the file, the camera and the
attribute.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_text_atomic
from silpose.shared.camera import RigError

from .calibration import CalibratedCamera, as_pixels, camera_matrix, rotation_from_values

__all__ = ["SUBPIXELS", "is_qualisys", "read_qualisys", "write_qualisys"]

#: QTM states intrinsics in sub-pixels: this many per pixel.
SUBPIXELS = 64.0
#: Qualisys camera axes (x right, y up, looking along -z) -> OpenCV's (x right, y down, looking along +z).
_FLIP = np.diag([1.0, -1.0, -1.0])
_ROTATION_KEYS = tuple(f"r{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))


def is_qualisys(path: str | Path) -> bool:
    """True for ``*.qca`` / ``*.qca.txt``, or an ``.xml`` / ``.txt`` file whose start holds ``<calibration``."""
    p = Path(path)
    name = p.name.lower()
    if name.endswith((".qca", ".qca.txt")):
        return True
    if p.suffix.lower() not in (".xml", ".txt"):
        return False
    try:
        with p.open("r", encoding="utf-8-sig", errors="replace") as f:
            head = f.read(4096)
    except OSError:
        return False
    return "<calibration" in head and "<opencv_storage" not in head


def _number(element: ET.Element, key: str, where: str) -> float:
    value = element.get(key)
    if value is None:
        raise RigError(f"{where}: missing attribute {element.tag}.{key}")
    try:
        x = float(value)
    except ValueError:
        raise RigError(f"{where}: attribute {element.tag}.{key}: expected a number, got {value!r}") from None
    if not np.isfinite(x):
        raise RigError(f"{where}: attribute {element.tag}.{key} is NaN or infinite")
    return x


def _child(camera: ET.Element, tag: str, where: str) -> ET.Element:
    element = camera.find(tag)
    if element is None:
        raise RigError(f"{where}: missing element <{tag}>")
    return element


def _camera(source: str, index: int, camera: ET.Element, notes: list[str]) -> CalibratedCamera:
    name = camera.get("serial") or f"camera{index}"
    where = f"{source}: camera {name!r}"
    fov = _child(camera, "fov_video", where)
    left, top = _number(fov, "left", where), _number(fov, "top", where)
    width = as_pixels(_number(fov, "right", where) - left + 1, f"{where}: fov_video width")
    height = as_pixels(_number(fov, "bottom", where) - top + 1, f"{where}: fov_video height")
    intr = _child(camera, "intrinsic", where)
    if intr.get("skew") not in (None, "") and _number(intr, "skew", where) != 0.0:
        raise RigError(f"{where}: attribute intrinsic.skew is not 0; silpose's cameras have no skew")
    fx, fy = (_number(intr, k, where) / SUBPIXELS for k in ("focalLengthU", "focalLengthV"))
    cx = _number(intr, "centerPointU", where) / SUBPIXELS - left
    cy = _number(intr, "centerPointV", where) / SUBPIXELS - top
    K = camera_matrix(np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]), f"{where}: intrinsic")

    def optional(key: str) -> float:
        return _number(intr, key, where) if intr.get(key) not in (None, "") else 0.0

    dist = np.array([optional("radialDistortion1"), optional("radialDistortion2"), optional("tangentalDistortion1"),
                     optional("tangentalDistortion2"), optional("radialDistortion3")])
    pose = _child(camera, "transform", where)
    M = np.array([_number(pose, k, where) for k in _ROTATION_KEYS]).reshape(3, 3)
    R = rotation_from_values(_FLIP @ M, f"{where}: transform r11..r33")
    centre = np.array([_number(pose, k, where) for k in ("x", "y", "z")])
    rotation = camera.get("viewrotation", "0")
    if rotation not in ("0", ""):
        notes.append(f"{where}: viewrotation {rotation} turns QTM's display only; not applied")
    return CalibratedCamera(name=name, K=K, dist=dist, R=R, t=-R @ centre, size=(width, height), source=source,
                            where=f"{name}.")


def read_qualisys(path: str | Path, notes: list[str] | None = None) -> list[CalibratedCamera]:
    """The active cameras of a QTM calibration (module docstring), in file order; ``notes`` gets what was left
    out or not applied."""
    source = str(path)
    notes = [] if notes is None else notes
    p = Path(path)
    if not p.is_file():
        raise RigError(f"{source}: calibration file not found")
    try:
        root = ET.parse(p).getroot()
    except (ET.ParseError, OSError) as exc:
        raise RigError(f"{source}: not a readable XML file ({exc})") from None
    calibration = root if root.tag == "calibration" else root.find(".//calibration")
    if calibration is None:
        raise RigError(f"{source}: no <calibration> element (a Qualisys .qca.txt calibration)")
    cameras = calibration.findall("cameras/camera")
    if not cameras:
        raise RigError(f"{source}: no <cameras>/<camera> element in <calibration>")
    out, inactive = [], []
    for i, camera in enumerate(cameras):
        if camera.get("active", "1") == "0":
            inactive.append(camera.get("serial") or f"camera{i}")
            continue
        out.append(_camera(source, i, camera, notes))
    if inactive:
        notes.append(f"{source}: inactive camera(s) {', '.join(inactive)} left out")
    if not out:
        raise RigError(f"{source}: every camera is inactive (active=\"0\")")
    names = [c.name for c in out]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise RigError(f"{source}: camera serial(s) {', '.join(twice)} used twice")
    return out


def write_qualisys(path: str | Path, cameras: list[CalibratedCamera]) -> Path:
    """Write cameras as a QTM calibration (tests and examples; k1, k2, p1, p2, k3 at most, no skew)."""
    root = ET.Element("calibration", {"source": "silpose", "type": "regular"})
    group = ET.SubElement(root, "cameras")
    for c in cameras:
        if c.size is None:
            raise ValueError(f"camera {c.name!r} has no image size")
        d = np.zeros(5)
        given = np.asarray(c.dist, dtype=np.float64).ravel()
        if c.fisheye or given.size > 5 and np.any(given[5:] != 0):
            raise ValueError(f"camera {c.name!r}: the QTM format has k1, k2, p1, p2, k3 only")
        d[: min(5, given.size)] = given[:5]
        K = np.asarray(c.K, dtype=np.float64)
        if K[0, 1] != 0:
            raise ValueError(f"camera {c.name!r}: skew is not written")
        R = np.asarray(c.R, dtype=np.float64)
        M = _FLIP @ R
        centre = -R.T @ np.asarray(c.t, dtype=np.float64)
        cam = ET.SubElement(group, "camera", {"active": "1", "serial": c.name, "viewrotation": "0", "model": "none"})
        ET.SubElement(cam, "fov_video", {"left": "0", "top": "0", "right": str(c.size[0] - 1),
                                         "bottom": str(c.size[1] - 1)})
        pose = {k: repr(float(v)) for k, v in zip(_ROTATION_KEYS, M.ravel())}
        pose.update({k: repr(float(v)) for k, v in zip("xyz", centre)})
        ET.SubElement(cam, "transform", pose)
        ET.SubElement(cam, "intrinsic", {
            "focalLengthU": repr(K[0, 0] * SUBPIXELS), "focalLengthV": repr(K[1, 1] * SUBPIXELS),
            "centerPointU": repr(K[0, 2] * SUBPIXELS), "centerPointV": repr(K[1, 2] * SUBPIXELS), "skew": "0",
            "radialDistortion1": repr(d[0]), "radialDistortion2": repr(d[1]), "radialDistortion3": repr(d[4]),
            "tangentalDistortion1": repr(d[2]), "tangentalDistortion2": repr(d[3])})
    ET.indent(root)
    text = "<?xml version='1.0' encoding='ASCII'?>\n" + ET.tostring(root, encoding="unicode") + "\n"
    return write_text_atomic(Path(path), text)
