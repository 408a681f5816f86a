"""The Blender adapter for motion-capture clips: import a BVH file with Blender's own importer and
read back every frame's joint positions. bpy is imported lazily inside the functions; call them
only in a spawned worker (docs/conventions.md, "Blender").

The import is ``bpy.ops.import_anim.bvh`` (the ``io_anim_bvh`` add-on bundled with the bpy wheel)
into an empty scene, with its defaults for BVH files: Y up and -Z forward converted to Blender's
Z up, native Euler rotation orders, one Blender frame per BVH frame (no frame-rate scaling), unit
scale (silpose applies ``scale`` itself). The importer turns BVH frame k (0-based) into Blender
frame ``1 + k``; each frame is evaluated with ``scene.frame_set`` and the pose bones' heads and
tails read with ``foreach_get`` (armature space; the importer applies its axis conversion to the
armature, whose world matrix is multiplied in anyway). Malformed files are rejected first by
:func:`silpose.datagen.motion.bvh_check.check_structure`; anything the importer itself raises becomes one line naming
the file.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from .scene import quiet_stdout
from .scene_clip import evaluate_armature, last_line
from ..motion.bvh_check import BvhError, check_structure

#: the UTF-8 byte-order mark a Windows editor may put before "HIERARCHY"
UTF8_BOM = b"\xef\xbb\xbf"


def import_clip(path: str | Path) -> tuple[dict, np.ndarray, np.ndarray]:
    """Import one BVH file and evaluate every frame.

    Returns:
        meta: ``names`` (B,) bone names in the importer's order, ``parents`` (B,) parent index or
            -1, ``frames``, ``frame_time`` (s), ``rest_heads`` / ``rest_tails`` (B, 3) rest-pose
            bone ends, ``importer`` (add-on version), ``blender`` (version string).
        heads, tails: (F, B, 3) float32 world positions of the bone heads and tails per frame, in
            the file's unit.
    Raises:
        BvhError: one line naming the file.
    """
    import bpy  # first: it puts Blender's script folders (addon_utils, io_anim_bvh) on sys.path
    import addon_utils
    import io_anim_bvh

    path = Path(path)
    structure = check_structure(path)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable("io_anim_bvh", default_set=False)
    with tempfile.TemporaryDirectory(prefix="silpose-bvh-") as tmp:
        raw = path.read_bytes()
        readable = path
        if raw.startswith(UTF8_BOM):  # a Windows editor's byte-order mark: the importer's first line would not read
            readable = Path(tmp) / path.name  # "HIERARCHY", so it gets a copy without the mark
            readable.write_bytes(raw[len(UTF8_BOM):])
        try:
            with quiet_stdout():
                bpy.ops.import_anim.bvh(
                    filepath=str(readable), target="ARMATURE", global_scale=1.0, frame_start=1, use_fps_scale=False,
                    update_scene_fps=False, update_scene_duration=False, use_cyclic=False, rotate_mode="NATIVE",
                    axis_forward="-Z", axis_up="Y",
                )
        except Exception as exc:  # the operator wraps the importer's error in a RuntimeError with its traceback
            raise BvhError(f"{path}: Blender's BVH importer failed ({last_line(exc)})") from None
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    if len(arms) != 1 or arms[0].animation_data is None or arms[0].animation_data.action is None:
        raise BvhError(f"{path}: Blender's BVH importer made no animated armature")
    arm = arms[0]
    first, last = (int(round(v)) for v in arm.animation_data.action.frame_range)
    n_frames = last - first + 1
    if first != 1 or n_frames != structure.frames:
        raise BvhError(f"{path}: Blender's importer made frames {first}..{last}, the file has {structure.frames}")
    meta, heads, tails = evaluate_armature(arm, first, n_frames, path, BvhError)
    meta.update(frame_time=structure.frame_time,
                importer="io_anim_bvh " + ".".join(str(v) for v in io_anim_bvh.bl_info.get("version", ())))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return meta, heads, tails
