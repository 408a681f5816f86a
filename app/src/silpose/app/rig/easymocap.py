"""EasyMocap calibrations: ``intri.yml`` + ``extri.yml`` (OpenCV FileStorage YAML).

Both files hold a ``names`` list; per camera ``<name>``: ``K_<name>`` (3x3) and ``dist_<name>`` in
``intri.yml`` (optionally ``H_<name>`` / ``W_<name>``, the image size), ``R_<name>`` (Rodrigues vector)
and/or ``Rot_<name>`` (3x3), and ``T_<name>`` in ``extri.yml`` (world->camera, calibration units).
The other file of the pair is found next to the one given. Cameras are the ``intri.yml`` names that
also have extrinsics, in that order, named as in the files; cameras with intrinsics only are
reported and left out. Other spellings of the fields are accepted as for OpenCV files
(:data:`.calibration.FIELD_ALIASES`).
"""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import cv2
import numpy as np

from silpose.shared.atomic import atomic_path
from silpose.shared.camera import RigError

from .calibration import CalibratedCamera, FieldReader, rotation_to_rvec
from .opencv import node_value, open_filestorage

__all__ = ["read_easymocap", "write_easymocap", "easymocap_pair", "is_easymocap"]

INTRI, EXTRI = "intri.yml", "extri.yml"


def easymocap_pair(path: str | Path) -> tuple[Path, Path]:
    """(intri.yml, extri.yml) of the pair ``path`` belongs to (the other is looked for next to it)."""
    p = Path(path)
    name = p.name.lower()
    if name.startswith("intri"):
        other = p.with_name(p.name.lower().replace("intri", "extri", 1))
        return p, next((q for q in (other, p.with_name(EXTRI)) if q.is_file()), other)
    if name.startswith("extri"):
        other = p.with_name(p.name.lower().replace("extri", "intri", 1))
        return next((q for q in (other, p.with_name(INTRI)) if q.is_file()), other), p
    raise RigError(f"{p}: an EasyMocap calibration is a pair intri.yml + extri.yml")


def is_easymocap(path: str | Path) -> bool:
    """True for a file named ``intri*.yml`` / ``extri*.yml`` (the EasyMocap pair)."""
    name = Path(path).name.lower()
    return name.startswith(("intri", "extri")) and Path(path).suffix.lower() in (".yml", ".yaml")


def _names(root, source: str) -> list[str]:
    node = root.getNode("names")
    if node.empty() or not node.isSeq():
        raise RigError(f"{source}: missing field names (the list of camera names)")
    out = []
    for i in range(node.size()):
        item = node.at(i)
        if item.isString():
            out.append(item.string())
        elif item.isInt() or item.isReal():
            v = item.real()
            out.append(str(int(v)) if v == int(v) else str(v))
        else:
            raise RigError(f"{source}: field names[{i}]: expected a camera name")
    if not out:
        raise RigError(f"{source}: field names: empty")
    if len(set(out)) != len(out):
        raise RigError(f"{source}: field names: camera names repeat ({out})")
    return out


def read_easymocap(path: str | Path, skipped: list[str] | None = None) -> list[CalibratedCamera]:
    """The cameras of the EasyMocap pair ``path`` belongs to (module docstring); the names of cameras
    with intrinsics only are appended to ``skipped``."""
    intri, extri = easymocap_pair(path)
    for p in (intri, extri):
        if not p.is_file():
            raise RigError(f"{p}: not found (an EasyMocap calibration is intri.yml + extri.yml side by side)")
    with ExitStack() as stack:
        roots = {str(intri): stack.enter_context(open_filestorage(intri)),
                 str(extri): stack.enter_context(open_filestorage(extri))}
        names_i = _names(roots[str(intri)], str(intri))
        names_e = _names(roots[str(extri)], str(extri))
        missing = [n for n in names_e if n not in names_i]
        if missing:
            raise RigError(f"{extri}: field names: camera(s) {', '.join(missing)} have no intrinsics in {intri}")
        owner = {}
        for src, root in roots.items():
            for k in root.keys():
                owner.setdefault(k, src)
        cams = []
        for name in names_i:
            if name not in names_e:
                if skipped is not None:
                    skipped.append(name)
                continue
            suffix = f"_{name}"
            keys = [k for k in owner if k.endswith(suffix)]

            def get(k, owner=owner):
                return node_value(roots[owner[k]].getNode(k), f"{owner[k]}: field {k}")

            reader = FieldReader(keys, get, f"{intri} + {extri}", "", suffix, source_of=owner.__getitem__)
            cam = reader.camera(name)
            cams.append(CalibratedCamera(cam.name, cam.K, cam.dist, cam.R, cam.t, cam.size, str(intri)))
    return cams


def write_easymocap(folder: str | Path, cameras: list[CalibratedCamera]) -> tuple[Path, Path]:
    """Write ``folder/intri.yml`` and ``folder/extri.yml`` as EasyMocap does (``R_`` Rodrigues and
    ``Rot_`` matrix, ``T_``; ``H_``/``W_`` when the size is known). Returns the two paths."""
    fisheye = [c.name for c in cameras if c.fisheye]
    if fisheye:
        raise ValueError(f"camera {fisheye[0]!r}: EasyMocap's files have no fisheye lens model")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for fname, items in ((INTRI, ("K", "dist", "H", "W")), (EXTRI, ("R", "Rot", "T"))):
        path = folder / fname
        with atomic_path(path) as tmp:
            fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
            try:
                fs.startWriteStruct("names", cv2.FileNode_SEQ)
                for c in cameras:
                    fs.write("", c.name)
                fs.endWriteStruct()
                for c in cameras:
                    values = {"K": np.asarray(c.K, np.float64), "dist": np.asarray(c.dist, np.float64).reshape(1, -1),
                              "R": rotation_to_rvec(c.R).reshape(3, 1), "Rot": np.asarray(c.R, np.float64),
                              "T": np.asarray(c.t, np.float64).reshape(3, 1)}
                    if c.size is not None:
                        values["W"], values["H"] = int(c.size[0]), int(c.size[1])
                    for key in items:
                        if key in values:
                            fs.write(f"{key}_{c.name}", values[key])
            finally:
                fs.release()
        out.append(path)
    return out[0], out[1]
