"""Camera calibrations in JSON: the layouts multi-view datasets and their toolboxes publish.

A ``.json`` file that is not a silpose rig (:func:`silpose.shared.camera.is_rig_dict`) is searched for
*camera records*: JSON objects holding intrinsics, a rotation and a translation, at any nesting up to
:data:`MAX_DEPTH` (a top-level list, ``{"cameras": [...]}``, ``{"<id>": {...}}`` ...). One reader covers
the layouts below, because they differ only in spellings and in what the translation means:

====================  ==============================================  =====================================
layout                camera record (example file)                    translation
====================  ==============================================  =====================================
anipose / AIST++      ``{name, size, matrix, distortions, rotation,    world -> camera (AIST++: cm)
                      translation}`` in a top-level list
                      (``cameras/setting1.json``)
CMU Panoptic          ``{"cameras": [{name, type, resolution, K,       world -> camera (cm)
                      distCoef, R, t}]}`` (``calibration_<seq>.json``)
Human3.6M style       ``{"<id>": {R, T, fx, fy, cx, cy, k, p}}`` or     camera centre: ``x_cam = R (X - T)``
                      ``f`` / ``c`` pairs (VoxelPose's Shelf and
                      Campus files, 3d-pose-baseline's cameras)
Human3.6M parameters  ``{"intrinsics": {cam: {calibration_matrix,     world -> camera (mm)
                      distortion}}, "extrinsics": {"S1": {cam: {R,
                      t}}}}`` (karfly/human36m-camera-parameters)
generic               the spellings of :data:`.calibration.FIELD_ALIASES`  world -> camera
====================  ==============================================  =====================================

Intrinsics are a 3x3 matrix or split: ``fx, fy, cx, cy`` (and an optional skew ``s``), or ``f`` = [fx, fy]
and ``c`` = [cx, cy]. Split distortion -- ``k`` (radial, up to 6) and ``p`` (tangential, 2), or scalars
``k1 .. k6``, ``p1``, ``p2`` -- is put in OpenCV's order ``k1, k2, p1, p2, k3[, k4, k5, k6]``.

**The translation.** ``auto`` reads it as world -> camera (``x_cam = R X + t``, OpenCV's convention and
every other format's) except in the Human3.6M parameterisation (split intrinsics *and* split ``k``/``p``
distortion), whose ``T`` is the camera's centre in the world (``x_cam = R (X - T)``, as 3d-pose-baseline's
and VoxelPose's ``project_point_radial`` use it); the import says which it took. ``--translation
world-to-camera`` or ``camera-centre`` overrides it. A record with ``"world2cam": false`` (XRPrimer) holds
the camera -> world pose and is inverted; its 4x4 ``intrinsic`` is read as the 3x3 camera matrix it holds.
Rotations are a Rodrigues vector or a matrix, as elsewhere.

Files that keep intrinsics and poses apart are joined by camera key: every pose record (a rotation and a
translation, no intrinsics) takes the intrinsics record of its own key. When a camera has poses in several
groups (Human3.6M's subjects ``S1`` .. ``S11``), cameras are named ``group/camera`` and the import asks for
one group (``--cameras 'S9/*'``), whose cameras then take their plain names
(:func:`.formats.read_calibrations`).

A record whose pose sits in one object inside it (``{"K": ..., "extrinsics": {"R": ..., "t": ...}}``) is read as
one camera.

A record is named by its ``name`` field, else by its key (``"0"`` .. in VoxelPose's files) or its index in
a list; records in a list are read in order. A record with intrinsics but no pose is an error naming it.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from silpose.shared.camera import RigError, is_rig_dict

from .calibration import (CalibratedCamera, FieldReader, camera_matrix, distortion, normalise_key,
                          rotation_from_values)

__all__ = ["read_json_calibration", "load_json", "TRANSLATIONS", "MAX_DEPTH", "MAX_BYTES", "is_silpose_rig_json"]

#: what ``--translation`` accepts (module docstring)
TRANSLATIONS = ("auto", "world-to-camera", "camera-centre")
#: nesting levels searched for camera records
MAX_DEPTH = 4
#: a calibration file larger than this (bytes) is refused (CMU Panoptic's, with 521 cameras, is ~0.6 MB)
MAX_BYTES = 64 << 20

_FOCAL = ("f", "focal", "focallength", "focallengths")
_CENTRE = ("c", "principalpoint", "pp")
_SKEW = ("s", "skew")
_RADIAL = ("k", "radial", "radialdistortion")
_TANGENTIAL = ("p", "tangential", "tangentialdistortion")


def load_json(path: str | Path):
    """The parsed JSON of a calibration file; RigError naming the file when it is not readable JSON."""
    p = Path(path)
    if not p.is_file():
        raise RigError(f"{p}: calibration file not found")
    if p.stat().st_size > MAX_BYTES:
        raise RigError(f"{p}: {p.stat().st_size / 2**20:.0f} MB is too large for a calibration file "
                       f"(at most {MAX_BYTES >> 20} MB)")
    try:
        return json.loads(p.read_text(encoding="utf-8-sig"))
    except (UnicodeDecodeError, OSError) as exc:
        raise RigError(f"{p}: cannot read this file as UTF-8 text ({exc})") from None
    except (json.JSONDecodeError, RecursionError) as exc:
        raise RigError(f"{p}: not valid JSON ({type(exc).__name__}: {exc})") from None


def is_silpose_rig_json(path: str | Path) -> bool:
    """True when ``path`` parses as JSON shaped like a silpose rig file (its errors then come from the rig loader)."""
    try:
        return is_rig_dict(load_json(path))
    except RigError:
        return True  # unreadable: let the rig loader say why


def _value(v):
    """A JSON value as FieldReader wants it: str, float array, or None (objects, booleans, ragged lists)."""
    if isinstance(v, str):
        return v
    if isinstance(v, bool) or isinstance(v, dict) or v is None:
        return None
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    return a


def _intrinsic_3x3(v):
    """A 4x4 intrinsic ``[[fx, s, cx, 0], [0, fy, cy, 0], [0, 0, 0, 1], [0, 0, 1, 0]]`` (XRPrimer; or with the last
    two rows swapped) as the 3x3 camera matrix; other values unchanged."""
    if isinstance(v, np.ndarray) and v.size == 16:
        m = v.reshape(4, 4)
        if m[0, 3] == 0 and m[1, 3] == 0 and sorted(map(tuple, m[2:])) == [(0, 0, 0, 1), (0, 0, 1, 0)]:
            return np.array([m[0, :3], m[1, :3], [0.0, 0.0, 1.0]])
    return v


def _scalar_keys(record: dict) -> dict[str, str]:
    """normalised key -> key as written, for the record's keys."""
    return {normalise_key(k): k for k in record}


def _numbers(record: dict, key: str, where: str, size: int | None = None) -> np.ndarray:
    v = _value(record[key])
    if v is None or isinstance(v, str):
        raise RigError(f"{where}{key}: expected numbers")
    if not np.all(np.isfinite(v)):
        raise RigError(f"{where}{key}: contains NaN or infinity")
    if size is not None and v.size != size:
        raise RigError(f"{where}{key}: expected {size} value(s), got shape {v.shape}")
    return v.ravel()


def _first(keys: dict[str, str], names) -> str | None:
    return next((keys[n] for n in names if n in keys), None)


def _split_intrinsics(record: dict, where: str) -> np.ndarray | None:
    """K from ``fx, fy, cx, cy`` (+ ``s``) or ``f`` / ``c`` pairs; None when the record has neither."""
    keys = _scalar_keys(record)
    if all(k in keys for k in ("fx", "fy", "cx", "cy")):
        fx, fy, cx, cy = (float(_numbers(record, keys[k], where, 1)[0]) for k in ("fx", "fy", "cx", "cy"))
    else:
        fk, ck = _first(keys, _FOCAL), _first(keys, _CENTRE)
        if fk is None or ck is None:
            return None
        f = _numbers(record, fk, where)
        if f.size == 1:
            f = np.repeat(f, 2)
        if f.size != 2:
            raise RigError(f"{where}{fk}: expected [fx, fy] (or one focal length), got {f.size} values")
        (fx, fy), (cx, cy) = f, _numbers(record, ck, where, 2)
    sk = _first(keys, _SKEW)
    skew = 0.0 if sk is None else float(_numbers(record, sk, where, 1)[0])
    return camera_matrix(np.array([[fx, skew, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]), f"{where}intrinsics")


def _split_distortion(record: dict, where: str) -> tuple[np.ndarray | None, bool]:
    """OpenCV-ordered coefficients from ``k`` / ``p`` lists or ``k1`` .. ``p2`` scalars (None when absent), and
    whether they came as ``k`` / ``p`` lists (the Human3.6M parameterisation)."""
    keys = _scalar_keys(record)
    # XRPrimer spells them distortion_k1 ...: read through a leading "distortion"
    for k in list(keys):
        if k.startswith("distortion") and k[len("distortion"):] in ("k1", "k2", "k3", "k4", "k5", "k6", "p1", "p2"):
            keys.setdefault(k[len("distortion"):], keys[k])
    rk, pk = _first(keys, _RADIAL), _first(keys, _TANGENTIAL)
    if rk is not None and isinstance(_value(record[rk]), np.ndarray) and _value(record[rk]).size in (9, 16):
        rk = None  # K: the camera matrix, not radial coefficients
    radial = np.zeros(0) if rk is None else _numbers(record, rk, where)
    tangential = np.zeros(2) if pk is None else _numbers(record, pk, where, 2)
    scalars = [k for k in ("k1", "k2", "k3", "k4", "k5", "k6") if k in keys]
    if scalars:
        if rk is not None:
            raise RigError(f"{where}{rk}: radial distortion given twice (also as {keys[scalars[0]]})")
        radial = np.array([float(_numbers(record, keys[k], where, 1)[0]) if k in keys else 0.0
                           for k in ("k1", "k2", "k3", "k4", "k5", "k6")[: int(scalars[-1][1])]])
    if "p1" in keys or "p2" in keys:
        if pk is not None:
            raise RigError(f"{where}{pk}: tangential distortion given twice (also as p1/p2)")
        tangential = np.array([float(_numbers(record, keys[k], where, 1)[0]) if k in keys else 0.0
                               for k in ("p1", "p2")])
    if rk is None and pk is None and not scalars and "p1" not in keys and "p2" not in keys:
        return None, False
    if radial.size > 6:
        raise RigError(f"{where}{rk}: expected at most 6 radial coefficients, got {radial.size}")
    r = np.concatenate([radial, np.zeros(6 - radial.size)])
    coeffs = np.array([r[0], r[1], tangential[0], tangential[1], r[2], r[3], r[4], r[5]])
    return distortion(coeffs if radial.size > 3 else coeffs[:5], f"{where}distortion"), rk is not None or pk is not None


def _has_intrinsics(node: dict) -> bool:
    keys = _scalar_keys(node)
    if all(k in keys for k in ("fx", "fy", "cx", "cy")) or (
            _first(keys, _FOCAL) is not None and _first(keys, _CENTRE) is not None):
        return True
    reader = FieldReader(tuple(node), lambda k: _value(node[k]), "")
    return any(isinstance(_intrinsic_3x3(_value(node[k])), np.ndarray) and _intrinsic_3x3(_value(node[k])).size == 9
               for k in reader.matches("camera matrix"))


def _has_pose(reader: FieldReader) -> bool:
    return bool(reader.matches("rotation")) and bool(reader.matches("translation"))


def _kind(node) -> str | None:
    """``"camera"`` (intrinsics and a pose), ``"intrinsics"`` (no pose), ``"pose"`` (a numeric rotation and
    translation, no intrinsics) or None."""
    if not isinstance(node, dict):
        return None
    reader = FieldReader(tuple(node), lambda k: _value(node[k]), "")
    if _has_intrinsics(node):
        return "camera" if _has_pose(reader) else "intrinsics"
    if not _has_pose(reader):
        return None
    rot = [_value(node[k]) for k in reader.matches("rotation")]
    tra = [_value(node[k]) for k in reader.matches("translation")]
    numeric = all(isinstance(v, np.ndarray) for v in rot + tra)
    return "pose" if numeric and all(v.size in (3, 9) for v in rot) and all(v.size == 3 for v in tra) else None


def _find_records(node, path: tuple[str, ...], depth: int, out: dict) -> None:
    """Fill ``out[kind]`` with ``(path, record)`` of every camera, intrinsics and pose record (:func:`_kind`)."""
    kind = _kind(node)
    if kind == "intrinsics":  # the pose one level down: {"K": ..., "extrinsics": {"R": ..., "t": ...}}
        nested = [v for v in node.values() if _kind(v) == "pose"]
        if len(nested) == 1:
            node, kind = {**{k: v for k, v in node.items() if v is not nested[0]}, **nested[0]}, "camera"
    if kind is not None:
        out.setdefault(kind, []).append((path, node))
        return
    if depth >= MAX_DEPTH:
        return
    if isinstance(node, dict):
        for k, v in node.items():
            _find_records(v, path + (str(k),), depth + 1, out)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            _find_records(v, path + (str(i),), depth + 1, out)


def _joined(source: str, found: dict, notes: list[str] | None) -> list[tuple[tuple[str, ...], dict, str | None]]:
    """Records of files that keep intrinsics and poses apart (Human3.6M's camera-parameters.json: ``intrinsics``
    per camera, ``extrinsics`` per subject and camera): each pose record joined with the intrinsics record of
    the same key, as ``(pose path, merged record, group)``; the group (the pose's parent key) only when the
    file holds several per camera."""
    intrinsics = {}
    for path, rec in found.get("intrinsics", []):
        key = path[-1] if path else ""
        intrinsics[key] = rec
        name = rec.get("name")
        if isinstance(name, str):
            intrinsics.setdefault(name, rec)
    poses = found.get("pose", [])
    groups = sorted({path[-2] if len(path) >= 2 else "" for path, _ in poses})
    out, used = [], set()
    for path, pose in poses:
        key = path[-1] if path else ""
        if key not in intrinsics:
            raise RigError(f"{source}: the pose at {_where(path)[:-1] or 'the top level'} has no intrinsics: no camera "
                           f"record named {key!r} with a camera matrix (K / matrix / calibration_matrix)")
        used.add(id(intrinsics[key]))
        merged = {**intrinsics[key], **pose}
        if not isinstance(merged.get("name"), str):
            merged["name"] = key
        group = (path[-2] if len(path) >= 2 else "") if len(groups) > 1 else None
        if group is not None:
            merged["name"] = f"{group}/{merged['name']}"
        out.append((path, merged, group))
    unused = [p[-1] for p, rec in found.get("intrinsics", []) if id(rec) not in used]
    if unused and notes is not None:
        notes.append(f"{source}: intrinsics without a pose left out: {', '.join(unused)}")
    return out


def _where(path: tuple[str, ...]) -> str:
    """``cameras[3].`` / ``0.``: the record's place in the file, as error prefixes use it."""
    out = ""
    for part in path:
        out += f"[{part}]" if part.isdigit() and out else ("." if out else "") + part
    return f"{out}." if out else ""


def _record_camera(source: str, path: tuple[str, ...], record: dict, translation: str) -> tuple[CalibratedCamera, bool]:
    """One camera, and whether its translation was read as the camera centre."""
    where = _where(path)
    reader = FieldReader(tuple(record), lambda k: _intrinsic_3x3(_value(record[k])), source, where)
    K = _split_intrinsics(record, f"{source}: field {where}")
    dist, human36m = _split_distortion(record, f"{source}: field {where}")
    if dist is not None and reader.matches("distortion"):
        raise RigError(f"{reader.field(reader.matches('distortion')[0])}: distortion given twice (also as k/p "
                       "coefficients)")
    if K is None:
        cam = reader.camera(path[-1] if path else Path(source).stem)
        if dist is not None:
            cam = CalibratedCamera(cam.name, cam.K, dist, cam.R, cam.t, cam.size, cam.source, cam.where)
        return cam, translation == "camera-centre"
    if not _has_pose(reader):
        raise reader.missing("rotation" if not reader.matches("rotation") else "translation")
    if dist is None:
        found = reader.numbers("distortion", required=False)
        dist = reader.agreed("distortion", found, distortion, 1e-12)[1] if found else np.zeros(5)
    _, R = reader.agreed("rotation", reader.numbers("rotation"), rotation_from_values, 1e-6)
    tk, t = reader.numbers("translation")[0]
    if t.size != 3:
        raise RigError(f"{reader.field(tk)}: expected 3 values, got shape {t.shape}")
    centre = translation == "camera-centre" or (translation == "auto" and human36m)
    name = reader.string("name") or (path[-1] if path else Path(source).stem)
    cam = CalibratedCamera(name=name, K=K, dist=dist, R=R, t=t.ravel(), size=reader.image_size(), source=source,
                           where=where)
    return cam, centre


def read_json_calibration(path: str | Path, translation: str = "auto",
                          notes: list[str] | None = None) -> list[CalibratedCamera]:
    """The cameras of a JSON calibration (module docstring), in file order, with world -> camera poses.

    ``translation``: one of :data:`TRANSLATIONS`. ``notes`` (optional) receives one line saying how the
    translations were read when a record's layout decided it.
    """
    if translation not in TRANSLATIONS:
        raise RigError(f"--translation: must be one of {', '.join(TRANSLATIONS)}, got {translation!r}")
    source = str(path)
    data = load_json(path)
    found: dict = {}
    _find_records(data, (), 0, found)
    records = [(path, rec, None) for path, rec in found.get("camera", [])]
    if found.get("pose") and found.get("intrinsics"):
        records += _joined(source, found, notes)
    else:
        records += [(path, rec, None) for path, rec in found.get("intrinsics", [])]  # missing pose: an error below
    if not records:
        raise RigError(f"{source}: no camera found in this JSON file (silpose looks for objects with a camera "
                       "matrix K / matrix / intrinsic (or fx, fy, cx, cy), a rotation R / rotation / rvec and a "
                       "translation t / T / translation, as in anipose, AIST++, CMU Panoptic or VoxelPose files, "
                       "or intrinsics and extrinsics per camera name, as in Human3.6M's camera-parameters.json)")
    cams, centred = [], []
    for rec_path, record, group in records:
        cam, centre = _record_camera(source, rec_path, record, translation)
        cam = dataclasses.replace(cam, group=group)
        if centre:
            cam = dataclasses.replace(cam, t=-cam.R @ cam.t)
            centred.append(cam.name)
        flag = record.get("world2cam", record.get("world_to_camera"))
        if flag is False:  # XRPrimer: the record holds camera -> world
            R_w2c = cam.R.T
            cam = dataclasses.replace(cam, R=R_w2c, t=-R_w2c @ cam.t)
        cams.append(cam)
    if notes is not None and centred and translation == "auto":
        notes.append(f"{source}: read the translation of {', '.join(centred)} as the camera centre (Human3.6M-style "
                     "record: split intrinsics and k/p distortion, x_cam = R (X - T)); --translation world-to-camera "
                     "if it is not")
    names = [c.name for c in cams]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise RigError(f"{source}: camera name(s) {', '.join(map(repr, twice))} used by more than one record; "
                       "names must be unique")
    return cams
