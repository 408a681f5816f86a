"""Skeletool / Captury ``.calibration`` files (MPI-INF-3DHP, DynaCap and other Max Planck multi-view sets).

A text file that starts with ``Skeletool Camera Calibration File V1.0``, then one block per camera::

    name          0
      sensor      10 10                       sensor width, height (mm; not needed)
      size        2048 2048                   image width, height (px)
      animated    0                           1: per-frame poses follow (refused)
      intrinsic   fx 0 cx 0  0 fy cy 0  0 0 1 0  0 0 0 1      4x4, row-major
      extrinsic   r11 r12 r13 tx  r21 r22 r23 ty  r31 r32 r33 tz  0 0 0 1   world -> camera, 4x4
      radial      0                           the number of radial coefficients, then the coefficients

The extrinsic maps the calibration's world to the camera (``x_cam = R X + t``, in the calibration's unit:
millimetres for MPI-INF-3DHP). Radial coefficients are read as OpenCV's ``k1, k2[, k3]`` (at most 3); the
format has no tangential terms. Cameras are named by their ``name`` line, in file order. Every problem is a
one-line :class:`~silpose.shared.camera.RigError` naming the file, the camera and the line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_text_atomic
from silpose.shared.camera import RigError

from .calibration import CalibratedCamera, as_pixels, camera_matrix, rotation_from_values

__all__ = ["HEADER", "is_skeletool", "read_skeletool", "write_skeletool"]

HEADER = "Skeletool Camera Calibration File V1.0"
_KEYS = ("sensor", "size", "animated", "intrinsic", "extrinsic", "radial")


def is_skeletool(path: str | Path) -> bool:
    """True for a ``.calibration`` file, or any file whose first line is :data:`HEADER`."""
    p = Path(path)
    if p.suffix.lower() == ".calibration":
        return True
    try:
        with p.open("r", encoding="utf-8-sig", errors="replace") as f:
            return f.readline(len(HEADER) + 8).strip() == HEADER
    except OSError:
        return False


def _floats(values: list[str], where: str) -> np.ndarray:
    try:
        v = np.array([float(x) for x in values])
    except ValueError:
        raise RigError(f"{where}: expected numbers, got {' '.join(values)!r}") from None
    if not np.all(np.isfinite(v)):
        raise RigError(f"{where}: contains NaN or infinity")
    return v


def _camera(source: str, name: str, fields: dict[str, tuple[int, list[str]]]) -> CalibratedCamera:
    def where(key: str) -> str:
        return f"{source}: camera {name!r}, line {fields[key][0]} ({key})"

    for key in ("size", "intrinsic", "extrinsic"):
        if key not in fields:
            raise RigError(f"{source}: camera {name!r}: missing line {key}")
    if "animated" in fields and _floats(fields["animated"][1], where("animated")).tolist() != [0.0]:
        raise RigError(f"{where('animated')}: an animated (moving) camera; silpose needs fixed cameras")
    size = _floats(fields["size"][1], where("size"))
    if size.size != 2:
        raise RigError(f"{where('size')}: expected width and height, got {size.size} values")
    width, height = as_pixels(size[0], where("size") + " [width]"), as_pixels(size[1], where("size") + " [height]")
    intrinsic = _floats(fields["intrinsic"][1], where("intrinsic"))
    if intrinsic.size != 16:
        raise RigError(f"{where('intrinsic')}: expected 16 values (a 4x4 matrix), got {intrinsic.size}")
    m = intrinsic.reshape(4, 4)
    if m[0, 3] != 0 or m[1, 3] != 0 or m[2].tolist() != [0, 0, 1, 0] or m[3].tolist() != [0, 0, 0, 1]:
        raise RigError(f"{where('intrinsic')}: expected [[fx, s, cx, 0], [0, fy, cy, 0], [0, 0, 1, 0], [0, 0, 0, 1]]")
    K = camera_matrix(m[:3, :3].copy(), where("intrinsic"))
    extrinsic = _floats(fields["extrinsic"][1], where("extrinsic"))
    if extrinsic.size != 16:
        raise RigError(f"{where('extrinsic')}: expected 16 values (a 4x4 matrix), got {extrinsic.size}")
    e = extrinsic.reshape(4, 4)
    if not np.allclose(e[3], [0, 0, 0, 1]):
        raise RigError(f"{where('extrinsic')}: the last row must be 0 0 0 1")
    R = rotation_from_values(e[:3, :3].copy(), where("extrinsic"))
    dist = np.zeros(5)
    if "radial" in fields:
        radial = _floats(fields["radial"][1], where("radial"))
        count = int(radial[0]) if radial.size else 0
        if radial.size == 0 or radial[0] != count or count < 0 or radial.size != count + 1:
            raise RigError(f"{where('radial')}: expected the number of coefficients, then that many coefficients")
        if count > 3:
            raise RigError(f"{where('radial')}: {count} radial coefficients; silpose reads at most 3 (OpenCV k1-k3)")
        dist[[0, 1, 4][:count]] = radial[1:]
    return CalibratedCamera(name=name, K=K, dist=dist, R=R, t=e[:3, 3].copy(), size=(width, height), source=source,
                            where=f"{name}.")


def read_skeletool(path: str | Path) -> list[CalibratedCamera]:
    """The cameras of a Skeletool ``.calibration`` file (module docstring), in file order."""
    source = str(path)
    p = Path(path)
    if not p.is_file():
        raise RigError(f"{source}: calibration file not found")
    try:
        lines = p.read_text(encoding="utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise RigError(f"{source}: cannot read this file as text ({exc})") from None
    if not lines or lines[0].strip() != HEADER:
        raise RigError(f"{source}: line 1: expected {HEADER!r} (a Skeletool / Captury calibration file)")
    blocks: list[tuple[str, dict]] = []
    for number, line in enumerate(lines[1:], start=2):
        words = line.split()
        if not words:
            continue
        key = words[0].lower()
        if key == "name":
            if len(words) != 2:
                raise RigError(f"{source}: line {number}: expected 'name <camera>'")
            if any(name == words[1] for name, _ in blocks):
                raise RigError(f"{source}: line {number}: camera name {words[1]!r} used twice")
            blocks.append((words[1], {}))
        elif key in _KEYS:
            if not blocks:
                raise RigError(f"{source}: line {number}: {key} before the first 'name' line")
            if key in blocks[-1][1]:
                raise RigError(f"{source}: line {number}: camera {blocks[-1][0]!r} has a second {key} line")
            blocks[-1][1][key] = (number, words[1:])
        else:
            raise RigError(f"{source}: line {number}: unknown line {words[0]!r} (expected name or one of "
                           f"{', '.join(_KEYS)})")
    if not blocks:
        raise RigError(f"{source}: no camera (no 'name' line)")
    return [_camera(source, name, fields) for name, fields in blocks]


def write_skeletool(path: str | Path, cameras: list[CalibratedCamera]) -> Path:
    """Write cameras as a Skeletool file (tests and examples; radial k1, k2, k3 only, no tangential terms)."""
    out = [HEADER]
    for c in cameras:
        if c.size is None:
            raise ValueError(f"camera {c.name!r} has no image size")
        d = np.asarray(c.dist, dtype=np.float64)
        if c.fisheye or d.size >= 4 and np.any(d[2:4] != 0) or d.size > 5:
            raise ValueError(f"camera {c.name!r}: the Skeletool format has only radial k1, k2, k3")
        radial = [float(x) for x in (d[[0, 1, 4]] if d.size == 5 else d[:2])]
        while radial and radial[-1] == 0.0:
            radial.pop()
        K = np.asarray(c.K, dtype=np.float64)
        intrinsic = np.eye(4)
        intrinsic[:3, :3] = K
        extrinsic = np.eye(4)
        extrinsic[:3, :3], extrinsic[:3, 3] = c.R, c.t
        out += [f"name          {c.name}", "  sensor      10 10", f"  size        {c.size[0]} {c.size[1]}",
                "  animated    0", "  intrinsic   " + " ".join(repr(float(x)) for x in intrinsic.ravel()),
                "  extrinsic   " + " ".join(repr(float(x)) for x in extrinsic.ravel()),
                "  radial      " + " ".join([str(len(radial))] + [repr(x) for x in radial])]
    return write_text_atomic(Path(path), "\n".join(out) + "\n")
