"""The Blender side of :mod:`silpose.datagen.bvh_export`: fit an armature to joints and export it as BVH.

Call only in a spawned worker whose parent never imported bpy (docs/conventions.md, "Blender"). One bone
per joint, its head at the joint's rest position (the first frame), pointing at its first child (a leaf
continues its parent's direction), bones not connected, so every joint keeps position channels. Per frame
each bone's armature-space matrix is set in hierarchy order: the rotation that turns its rest direction
towards its first child's current position (a leaf turns with its parent), and the translation that puts its
head exactly on the joint; location and rotation are keyed, and ``bpy.ops.export_anim.bvh`` (the bundled
``io_anim_bvh``) writes every frame with position channels on every joint, at unit scale, in Euler angles.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

LEAF_LENGTH = 0.05  # length of a leaf bone along its parent's direction (BVH End Site), in the joints' units


def write_bvh(message: dict) -> None:
    """``message``: ``joints`` (T, J, 3) list (Y up), ``fps``, ``names`` (J,), ``parents`` (J,), ``path``."""
    import bpy  # first: it puts Blender's script folders (addon_utils, io_anim_bvh) on sys.path
    import addon_utils
    from mathutils import Matrix, Vector

    from .scene import quiet_stdout

    joints = np.asarray(message["joints"], float)
    names, parents = list(message["names"]), list(message["parents"])
    n_frames, n_joints = joints.shape[:2]
    children = {j: [c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)}

    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable("io_anim_bvh", default_set=False)
    scene = bpy.context.scene
    rate = Fraction(float(message["fps"])).limit_denominator(1001)
    scene.render.fps, scene.render.fps_base = rate.numerator, rate.numerator / float(message["fps"])
    scene.frame_start, scene.frame_end = 1, n_frames

    arm = bpy.data.armatures.new("silpose")
    obj = bpy.data.objects.new("silpose", arm)
    scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)

    rest = joints[0]

    def direction(frame: np.ndarray, j: int) -> np.ndarray | None:
        if children[j]:
            return frame[children[j][0]] - frame[j]
        return None

    bpy.ops.object.mode_set(mode="EDIT")
    for j, name in enumerate(names):
        bone = arm.edit_bones.new(name)
        bone.head = Vector(rest[j])
        d = direction(rest, j)
        if d is None or np.linalg.norm(d) < 1e-9:
            p = parents[j]
            d = rest[j] - rest[p] if p >= 0 else np.array([0.0, 1.0, 0.0])
            d = d / max(np.linalg.norm(d), 1e-9) * LEAF_LENGTH
        bone.tail = Vector(rest[j] + d)
        bone.use_connect = False
    for j, name in enumerate(names):
        if parents[j] >= 0:
            arm.edit_bones[name].parent = arm.edit_bones[names[parents[j]]]
    bpy.ops.object.mode_set(mode="POSE")

    rest_mats = [arm.bones[n].matrix_local.copy() for n in names]
    order = sorted(range(n_joints), key=lambda j: _depth(parents, j))
    for f in range(n_frames):
        swing: dict[int, Matrix] = {}
        for j in order:
            pb = obj.pose.bones[names[j]]
            pb.rotation_mode = "QUATERNION"
            d_rest, d_now = direction(rest, j), direction(joints[f], j)
            if d_rest is not None and np.linalg.norm(d_rest) > 1e-9 and np.linalg.norm(d_now) > 1e-9:
                swing[j] = Vector(d_rest).rotation_difference(Vector(d_now)).to_matrix().to_4x4()
            else:
                swing[j] = swing.get(parents[j], Matrix.Identity(4))
            rot = swing[j] @ Matrix(rest_mats[j].to_3x3()).to_4x4()
            pb.matrix = Matrix.Translation(Vector(joints[f, j])) @ rot
            bpy.context.view_layer.update()  # the children's matrices are set against this pose
        for j in order:
            pb = obj.pose.bones[names[j]]
            pb.keyframe_insert("location", frame=f + 1)
            pb.keyframe_insert("rotation_quaternion", frame=f + 1)
    bpy.ops.object.mode_set(mode="OBJECT")
    with quiet_stdout():
        bpy.ops.export_anim.bvh(filepath=message["path"], check_existing=False, frame_start=1, frame_end=n_frames,
                                global_scale=1.0, rotate_mode="NATIVE", root_transform_only=False)


def _depth(parents: list[int], j: int) -> int:
    d = 0
    while parents[j] >= 0:
        j, d = parents[j], d + 1
    return d
