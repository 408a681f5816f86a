"""The Blender adapter for FBX and glTF motion clips (Mixamo, Rokoko, game-engine exports): import the
file with Blender's bundled importer (``io_scene_fbx``, ``io_scene_gltf2``) and read back every
frame's bone positions; also the armature evaluation the BVH adapter (:mod:`.bvh`) shares. bpy is
imported lazily inside the functions; call them only in a spawned worker (docs/conventions.md,
"Blender").

The importers' defaults are kept (FBX and glTF are Y up; both importers turn them to Blender's Z
up and to metres, so these clips come in metres: ``scale`` 1). The clip is the one animated
armature of the file (a skinned mesh beside it is ignored). A file with no armature but animated
nodes (an animation-only glTF, e.g. a Mixamo clip exported without its skin, comes in as a tree of
empties) gives one "bone" per node of the animated trees: its head the node's world position, its
tail the mean of its children's heads (a leaf: half its parent's segment further on). Frames:

- FBX states its frame rate: the importer sets the scene's, and each frame of the action is read;
- glTF keys are in seconds and state no rate: the scene's rate is set to :data:`GLTF_FPS` before
  the import, so the clip is sampled every 1 / GLTF_FPS s.

Heads and tails are read with ``foreach_get`` in armature space and moved to world space by the
armature's world matrix (a Mixamo FBX's armature is scaled 0.01 and turned 90 degrees).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .scene import quiet_stdout

#: Clip files read by :func:`import_scene_clip` (lower-case suffixes).
SCENE_SUFFIXES: tuple[str, ...] = (".fbx", ".glb", ".gltf")
#: Frames per second a glTF clip is sampled at (glTF keys are in seconds).
GLTF_FPS = 30


class SceneClipError(ValueError):
    """An FBX or glTF clip cannot be used; the message is one line naming the file."""


def last_line(exc: BaseException) -> str:
    """The last meaningful line of an importer's error (the operator wraps it in a traceback)."""
    lines = [ln.strip() for ln in str(exc).strip().splitlines() if ln.strip() and not ln.strip().startswith("Location:")]
    return lines[-1] if lines else type(exc).__name__


def animated_armature(path: Path, error: type[ValueError]):
    """The one armature of the scene with an action; ``error`` (one line naming ``path``) otherwise."""
    import bpy

    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    animated = [o for o in arms if o.animation_data is not None and o.animation_data.action is not None]
    if not animated:
        raise error(f"{path}: no animated armature in the file ({len(arms)} armatures, none with an animation)")
    if len(animated) > 1:
        raise error(f"{path}: {len(animated)} animated armatures ({', '.join(o.name for o in animated[:4])}); "
                    f"export one character per file")
    return animated[0]


def evaluate_armature(arm, first: int, n_frames: int, path: Path, error: type[ValueError]) -> tuple[dict, np.ndarray, np.ndarray]:
    """Bone names, parents, rest pose and (F, B, 3) float32 world heads and tails of Blender frames
    ``first`` .. ``first + n_frames - 1`` of armature object ``arm`` (``meta`` without the frame
    time and importer)."""
    import bpy

    bones = arm.pose.bones
    names = [b.name for b in bones]
    index = {n: i for i, n in enumerate(names)}
    parents = [index[b.parent.name] if b.parent is not None else -1 for b in bones]
    M = np.array(arm.matrix_world)
    rest_heads = np.array([arm.data.bones[n].head_local for n in names]) @ M[:3, :3].T + M[:3, 3]
    rest_tails = np.array([arm.data.bones[n].tail_local for n in names]) @ M[:3, :3].T + M[:3, 3]
    B = len(names)
    heads = np.empty((n_frames, B, 3), np.float32)
    tails = np.empty((n_frames, B, 3), np.float32)
    buf = np.empty(B * 3, np.float32)
    scene = bpy.context.scene
    for k in range(n_frames):
        scene.frame_set(first + k)
        M = np.array(arm.matrix_world)  # an animated armature object moves too
        bones.foreach_get("head", buf)
        heads[k] = (buf.reshape(B, 3).astype(np.float64) @ M[:3, :3].T + M[:3, 3]).astype(np.float32)
        bones.foreach_get("tail", buf)
        tails[k] = (buf.reshape(B, 3).astype(np.float64) @ M[:3, :3].T + M[:3, 3]).astype(np.float32)
    if not (np.all(np.isfinite(heads)) and np.all(np.isfinite(tails))):
        raise error(f"{path}: the imported motion contains NaN or infinity")
    meta = {"names": names, "parents": parents, "frames": n_frames, "rest_heads": rest_heads.tolist(),
            "rest_tails": rest_tails.tolist(), "blender": bpy.app.version_string}
    return meta, heads, tails


def _animated(obj) -> bool:
    return obj.animation_data is not None and obj.animation_data.action is not None


def _frames(path: Path, ranges) -> tuple[int, int]:
    """First and last whole frame of the animation ``ranges`` ((start, end) pairs)."""
    start, end = min(r[0] for r in ranges), max(r[1] for r in ranges)
    first, last = int(round(start)), int(round(end))
    if last <= first:
        raise SceneClipError(f"{path}: the animation has one frame ({start:g} .. {end:g}); a clip needs two or more")
    return first, last


def animated_nodes() -> list:
    """The empties of the trees that hold an animated empty, parents before children ([] if none)."""
    import bpy

    empties = [o for o in bpy.data.objects if o.type == "EMPTY"]
    roots = set()
    for o in empties:
        if _animated(o):
            while o.parent is not None and o.parent.type == "EMPTY":
                o = o.parent
            roots.add(o.name)
    out, stack = [], sorted(roots, reverse=True)
    while stack:
        o = bpy.data.objects[stack.pop()]
        out.append(o)
        stack.extend(sorted((c.name for c in o.children if c.type == "EMPTY"), reverse=True))
    return out


def evaluate_nodes(nodes: list, first: int, n_frames: int, path: Path) -> tuple[dict, np.ndarray, np.ndarray]:
    """As :func:`evaluate_armature`, for a tree of animated empties (module docstring)."""
    import bpy

    names = [o.name for o in nodes]
    index = {n: i for i, n in enumerate(names)}
    parents = [index[o.parent.name] if o.parent is not None and o.parent.name in index else -1 for o in nodes]
    children = [[c for c, p in enumerate(parents) if p == i] for i in range(len(names))]

    def ends(h: np.ndarray) -> np.ndarray:
        t = np.empty_like(h)
        for i, kids in enumerate(children):
            if kids:
                t[i] = h[kids].mean(axis=0)
            elif parents[i] >= 0:
                t[i] = h[i] + 0.5 * (h[i] - h[parents[i]])
            else:
                t[i] = h[i]
        return t

    scene = bpy.context.scene
    heads = np.empty((n_frames, len(names), 3), np.float64)
    for k in range(n_frames):
        scene.frame_set(first + k)
        heads[k] = [tuple(o.matrix_world.translation) for o in nodes]
    if not np.all(np.isfinite(heads)):
        raise SceneClipError(f"{path}: the imported motion contains NaN or infinity")
    tails = np.stack([ends(h) for h in heads])
    # the nodes' rest pose: their first frame (it only serves the joint map's checks)
    meta = {"names": names, "parents": parents, "frames": n_frames, "rest_heads": heads[0].tolist(),
            "rest_tails": tails[0].tolist(), "blender": bpy.app.version_string}
    return meta, heads.astype(np.float32), tails.astype(np.float32)


def import_scene_clip(path: str | Path) -> tuple[dict, np.ndarray, np.ndarray]:
    """Import one FBX or glTF (``.glb``/``.gltf``) clip and evaluate every frame (module docstring).

    Returns:
        meta, heads, tails as :func:`silpose.datagen.blender.bvh.import_clip`'s, positions in metres.
    Raises:
        SceneClipError: one line naming the file.
    """
    import bpy  # first: it puts Blender's script folders (addon_utils, the importers) on sys.path
    import addon_utils

    path = Path(path)
    if not path.is_file():
        raise SceneClipError(f"{path}: file not found")
    gltf = path.suffix.lower() in (".glb", ".gltf")
    module = "io_scene_gltf2" if gltf else "io_scene_fbx"
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable(module, default_set=False)
    scene = bpy.context.scene
    if gltf:
        scene.render.fps, scene.render.fps_base = GLTF_FPS, 1.0
    try:
        with quiet_stdout():
            if gltf:
                bpy.ops.import_scene.gltf(filepath=str(path))
            else:
                bpy.ops.import_scene.fbx(filepath=str(path))
    except Exception as exc:  # the operator wraps the importer's error in a RuntimeError with its traceback
        raise SceneClipError(f"{path}: Blender's {'glTF' if gltf else 'FBX'} importer failed ({last_line(exc)})") from None
    nodes = animated_nodes()
    if nodes and not any(o.type == "ARMATURE" for o in bpy.data.objects):
        first, last = _frames(path, [o.animation_data.action.frame_range for o in nodes if _animated(o)])
        meta, heads, tails = evaluate_nodes(nodes, first, last - first + 1, path)
    else:
        arm = animated_armature(path, SceneClipError)
        first, last = _frames(path, [arm.animation_data.action.frame_range])
        meta, heads, tails = evaluate_armature(arm, first, last - first + 1, path, SceneClipError)
    version = next((m.bl_info.get("version", ()) for m in addon_utils.modules() if m.__name__ == module), ())
    meta.update(frame_time=float(scene.render.fps_base) / float(scene.render.fps),
                importer=f"{module} " + ".".join(str(v) for v in version))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return meta, heads, tails
