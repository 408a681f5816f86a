"""Pose2Sim / anipose calibrations: one TOML file, one table per camera.

Each camera table (``[cam_01]``, ``[int_cam01_img]``, ``[cam_0]`` ...) holds ``name``, ``size``
([width, height]), ``matrix`` (3x3), ``distortions`` (k1, k2, p1, p2[, k3]), ``rotation``
(Rodrigues vector) and ``translation`` (world->camera, in the calibration's unit: metres for
Pose2Sim, the board's unit for anipose), and optionally ``fisheye`` (true: ``distortions`` are the 4
coefficients k1..k4 of OpenCV's fisheye model, as aniposelib's ``FisheyeCamera`` writes them). Tables without a camera matrix (``[metadata]``) are
skipped. The camera is named by ``name``, else by its table's key. Other spellings of the fields
are accepted as for OpenCV files (:data:`.calibration.FIELD_ALIASES`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_text_atomic
from silpose.shared.camera import RigError

from .calibration import CalibratedCamera, FieldReader, rotation_to_rvec

__all__ = ["read_pose2sim", "write_pose2sim"]


def _value(v, where: str):
    if isinstance(v, str):
        return v
    if isinstance(v, bool):
        return None
    try:
        return np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        return None


def read_pose2sim(path: str | Path) -> list[CalibratedCamera]:
    """The cameras of a Pose2Sim / anipose ``.toml`` calibration, in file order."""
    source = str(path)
    p = Path(path)
    if not p.is_file():
        raise RigError(f"{source}: calibration file not found")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8-sig"))  # a Windows editor's byte-order mark
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, OSError) as exc:
        raise RigError(f"{source}: not a readable TOML file ({str(exc).splitlines()[0]})") from None
    cams = []
    for key, table in data.items():
        if not isinstance(table, dict):
            continue
        reader = FieldReader(tuple(table), lambda k, t=table, key=key: _value(t[k], f"{key}.{k}"), source, f"{key}.")
        if not reader.matches("camera matrix"):
            continue
        fisheye = table.get("fisheye", False)
        if not isinstance(fisheye, bool):
            raise RigError(f"{source}: field {key}.fisheye: expected true or false, got {fisheye!r}")
        cam = reader.camera(key)
        if fisheye:
            if np.asarray(cam.dist).size != 4:
                raise RigError(f"{source}: field {key}.distortions: a fisheye camera has 4 coefficients (k1, k2, k3, "
                               f"k4), got {np.asarray(cam.dist).size}")
            cam = dataclasses.replace(cam, fisheye=True)
        cams.append(cam)
    if not cams:
        raise RigError(f"{source}: no camera table (a [cam_*] table with name, size, matrix, distortions, rotation, "
                       "translation)")
    return cams


def _toml_list(values) -> str:
    def num(x):
        x = float(x)
        if not math.isfinite(x):
            raise ValueError("TOML calibrations hold finite numbers only")
        return repr(x)
    return "[ " + ", ".join(num(x) for x in values) + ",]"


def write_pose2sim(path: str | Path, cameras: list[CalibratedCamera]) -> Path:
    """Write a Pose2Sim-style ``Calib.toml`` (``[cam_XX]`` tables, Rodrigues rotations, ``[metadata]``)."""
    lines = []
    for i, c in enumerate(cameras, start=1):
        lines += [f"[cam_{i:02d}]", f"name = {json.dumps(c.name)}"]
        if c.size is not None:
            lines.append(f"size = {_toml_list(c.size)}")
        lines += [
            "matrix = [ " + ", ".join(_toml_list(row) for row in np.asarray(c.K)) + ",]",
            f"distortions = {_toml_list(np.asarray(c.dist).ravel())}",
            f"rotation = {_toml_list(rotation_to_rvec(c.R))}",
            f"translation = {_toml_list(np.asarray(c.t).ravel())}",
            f"fisheye = {'true' if c.fisheye else 'false'}",
            "",
        ]
    lines += ["[metadata]", "adjusted = false", "error = 0.0", ""]
    return write_text_atomic(Path(path), "\n".join(lines))
