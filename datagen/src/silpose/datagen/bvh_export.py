"""BVH export of joints through Blender's own exporter, driven from a process that never imports bpy.

:func:`export_bvh` builds the job (the 19-joint skeleton, the joints per frame in the BVH's axes, the frame
rate) and runs :func:`silpose.datagen.blender.bvh_writer.write_bvh` in one spawned worker
(:func:`silpose.datagen.executor.spawned_map`), which fits the armature to the joints and calls
``bpy.ops.export_anim.bvh``. The file is written to a temporary name and renamed (:mod:`silpose.shared.atomic`).

The BVH file: one JOINT per silpose joint, named as in :data:`silpose.shared.skeleton.JOINT_NAMES`, its
OFFSET the joint's rest position relative to its parent; every joint has position and rotation channels
(``Xposition Yposition Zposition`` and Euler angles), so each frame reproduces the joints exactly, bone lengths
included. Axes: Y up, as BVH readers (Blender's importer, game engines) assume: silpose's ``(x, y, z)`` with z
up is written as ``(x, z, -y)``; units are the motion's (BVH has no unit field; metres unless the calibration
frame is in other units); ``Frame Time`` is ``1 / fps``. Frames without joints hold the nearest earlier pose
(the first valid pose before the first valid frame).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import atomic_path
from silpose.shared.skeleton import JOINT_NAMES, PARENTS

from .executor import WorkerDied, spawned_map

__all__ = ["export_bvh", "BvhExportError", "Y_UP_FROM_Z_UP", "fill_missing"]

#: silpose (x, y, z up) -> BVH (x, y up, z): a proper rotation about x.
Y_UP_FROM_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
WORKER = "silpose.datagen.blender.bvh_writer:write_bvh"


class BvhExportError(ValueError):
    """Blender could not write the BVH; one line."""


def fill_missing(joints: np.ndarray) -> np.ndarray:
    """(T, J, 3) with every frame holding a NaN replaced by the nearest earlier complete frame (the first
    complete frame for the leading ones); ValueError when no frame is complete."""
    joints = np.asarray(joints, float)
    ok = np.isfinite(joints).all(axis=(1, 2))
    if not ok.any():
        raise BvhExportError("no frame has joints: nothing to export")
    idx = np.where(ok, np.arange(len(joints)), -1)
    idx = np.maximum.accumulate(idx)
    idx[idx < 0] = np.flatnonzero(ok)[0]
    return joints[idx]


def _run(message: dict) -> str | None:
    from importlib import import_module

    module, name = WORKER.split(":")
    try:
        getattr(import_module(module), name)(message)
    except Exception as exc:  # returned, not raised: the driver reports it as one line
        return f"{type(exc).__name__}: {exc}"
    return None


def export_bvh(joints: np.ndarray, fps: float, path: str | Path, *, units: str = "m", up: str = "+z",
               source: str = "") -> Path:
    """Write ``joints`` (T, 19, 3) at ``fps`` as a BVH file ``path`` (module docstring). ``up``: the joints'
    up axis (``+z`` for silpose's frame: rotated to Y up; any other is written as it is)."""
    path = Path(path)
    filled = fill_missing(joints)
    if up == "+z":
        filled = filled @ Y_UP_FROM_Z_UP.T
    message = {"joints": filled.tolist(), "fps": float(fps), "names": list(JOINT_NAMES), "parents": list(PARENTS)}
    with atomic_path(path) as tmp:
        message["path"] = str(tmp)
        try:
            [(_, error)] = list(spawned_map(_run, [(0, message)], workers=1, max_tasks_per_child=1))
        except WorkerDied as exc:
            raise BvhExportError(f"{path}: the Blender worker died ({exc})") from None
        if error is not None:
            raise BvhExportError(f"{path}: Blender's BVH exporter failed ({error})")
    return path
