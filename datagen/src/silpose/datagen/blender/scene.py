"""The Blender adapter for bodies and silhouettes: the only place bpy is touched, with
:mod:`.frames.blender_room` (textured rooms). bpy is always imported lazily inside the functions
(docs/conventions.md, "Blender").

Call these functions only in a spawned worker process whose parent never imported bpy.

Body (docs/conventions.md, "Blender"): an armature with one bone per non-root joint (named after
its child joint, head at the parent joint), and a skeleton edge mesh with one vertex per joint
(plus the subject's clothing and hair vertices) carrying the modifiers Armature -> Skin
(per-vertex radii from :func:`silpose.datagen.subjects.joint_radii`) -> Subdivision, parented to
the armature. Vertex ``c`` is weighted 1 to bone ``c`` (the bone whose tail it is), so the
deformed skeleton passes exactly through the posed joints. The pose is a :class:`motion.Pose`:
a bone rotation ``R_c`` about the body rest axes is written as the pose bone's ``matrix_basis``
``B_c = L_c^T R_c L_c`` (``L_c`` = the bone's rest rotation, ``matrix_local``), which makes the
posed armature equal to the pose's forward kinematics. :func:`posed_body` is the one place a
sample's body is built, posed and read back.

Renders are silhouettes: ``film_transparent`` and the alpha channel > 0.5 is the mask.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from silpose.shared.camera import Rig
from silpose.shared.skeleton import JOINT_INDEX, JOINT_NAMES, N_JOINTS, PARENTS

from .camera import to_blender
from ..motion.source import BONES, Pose
from ..subjects import joint_radii, joint_type, segment_lengths
from ..walk import rest_skeleton

ENGINES = ("workbench", "cycles")


def reset_factory() -> None:
    """Empty Blender session (start of every shard)."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)


def setup_scene(rig: Rig, engine: str = "workbench", antialias: bool = False) -> list:
    """Configure render settings and create one Blender camera per rig camera.

    Args:
        rig: calibrated rig; every camera must be Blender compatible (fx == fy, no distortion).
        engine: ``"workbench"`` (flat, needs EGL) or ``"cycles"`` (CPU, 1 sample, box filter).
        antialias: anti-aliased render (for sub-pixel calibration checks), else hard masks.
    Returns:
        list of camera objects in rig order.
    """
    import bpy
    from mathutils import Matrix

    if engine not in ENGINES:
        raise ValueError(f"config field blender_engine: must be one of {ENGINES}, got {engine!r}")
    scene = bpy.context.scene
    W, H = rig.image_size
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.film_transparent = True
    r.use_compositing = False
    r.use_sequencer = False
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGBA"
    r.image_settings.color_depth = "8"
    if engine == "workbench":
        r.engine = "BLENDER_WORKBENCH"
        sh = scene.display.shading
        sh.light = "FLAT"
        sh.color_type = "SINGLE"
        sh.single_color = (1.0, 1.0, 1.0)
        sh.show_object_outline = False
        sh.show_cavity = False
        sh.show_shadows = False
        scene.display.render_aa = "16" if antialias else "OFF"
    else:
        r.engine = "CYCLES"
        c = scene.cycles
        c.device = "CPU"
        c.samples = 64 if antialias else 1
        c.use_adaptive_sampling = False
        c.use_denoising = False
        c.max_bounces = 0
        c.pixel_filter_type = "BOX"
        c.filter_width = 1.0 if antialias else 0.01
        c.seed = 0
    cams = []
    for cam in rig:
        p = to_blender(cam)
        data = bpy.data.cameras.new(cam.name)
        data.sensor_fit = "HORIZONTAL"
        data.sensor_width = p.sensor_width
        data.lens = p.lens
        data.shift_x, data.shift_y = p.shift_x, p.shift_y
        data.clip_start, data.clip_end = 0.05, 1000.0
        obj = bpy.data.objects.new(cam.name, data)
        scene.collection.objects.link(obj)
        obj.matrix_world = Matrix(p.matrix_world.tolist())
        cams.append(obj)
    return cams


def _extra_vertices(subject: dict, rest: np.ndarray, radii: dict) -> list[tuple[np.ndarray, float, int, dict]]:
    """Clothing/hair vertices: (rest position, radius, parent vertex index, {bone: weight}).

    Parent indices < N_JOINTS are joints; larger ones are earlier extra vertices. A skirt, dress or
    coat is a cone from its top (the pelvis, or the mid-torso ``spine`` joint for a coat) to its hem
    (radius ``skirt_flare``); a curved one (``skirt_curve`` != 0) gets a vertex half-way down whose
    radius is the straight cone's there plus ``skirt_curve``. Hems follow the thighs.
    """
    L = segment_lengths(subject)
    extra = []
    if subject["skirt_length"] > 0:
        pelvis = rest[JOINT_INDEX["pelvis"]]
        hem = pelvis - np.array([0.0, 0.0, subject["skirt_length"] * (L["thigh"] + L["shank"])])
        thighs = {"l_knee": 0.5, "r_knee": 0.5}
        top = JOINT_INDEX["spine"] if subject["skirt_top"] >= 0.5 else JOINT_INDEX["pelvis"]
        flare = float(subject["skirt_flare"])
        if subject["skirt_curve"] != 0:
            r_top = radii[JOINT_NAMES[top]]
            mid = 0.5 * (rest[top] + hem)
            r_mid = max(0.5 * (r_top + flare) + float(subject["skirt_curve"]), 0.02)
            extra.append((mid, r_mid, top, thighs))
            top = N_JOINTS + len(extra) - 1
        extra.append((hem, flare, top, thighs))
    if subject["hair_length"] > 0:
        head = rest[JOINT_INDEX["head"]]
        tip = head + np.array([-float(subject["hair_back"]) * radii["head"], 0.0, -float(subject["hair_length"])])
        extra.append((tip, 0.6 * radii["head"], JOINT_INDEX["head"], {"head_top": 1.0}))
    return extra


def build_body(subject: dict, subdivision_levels: int = 1) -> tuple:
    """Create the armature and skinned body of ``subject`` in rest pose.

    Returns:
        (armature object, body mesh object).
    """
    import bpy

    scene = bpy.context.scene
    rest = rest_skeleton(subject)
    radii = joint_radii(subject)

    arm_data = bpy.data.armatures.new("skeleton")
    arm_obj = bpy.data.objects.new("skeleton", arm_data)
    scene.collection.objects.link(arm_obj)
    bpy.context.view_layer.objects.active = arm_obj
    bpy.ops.object.mode_set(mode="EDIT")
    ebones = {}
    for c in range(1, N_JOINTS):
        eb = arm_data.edit_bones.new(JOINT_NAMES[c])
        eb.head = rest[PARENTS[c]].tolist()
        eb.tail = rest[c].tolist()
        eb.roll = 0.0
        if PARENTS[c] > 0:
            eb.parent = ebones[JOINT_NAMES[PARENTS[c]]]
        ebones[JOINT_NAMES[c]] = eb
    bpy.ops.object.mode_set(mode="OBJECT")

    extra = _extra_vertices(subject, rest, radii)
    verts = [tuple(v) for v in rest] + [tuple(e[0]) for e in extra]
    edges = [(PARENTS[c], c) for c in range(1, N_JOINTS)] + [(e[2], N_JOINTS + i) for i, e in enumerate(extra)]
    mesh = bpy.data.meshes.new("body")
    mesh.from_pydata(verts, edges, [])
    body = bpy.data.objects.new("body", mesh)
    scene.collection.objects.link(body)
    body.parent = arm_obj
    groups = {b: body.vertex_groups.new(name=b) for b in BONES}
    for c in range(1, N_JOINTS):
        groups[JOINT_NAMES[c]].add([c], 1.0, "REPLACE")
    for i, e in enumerate(extra):
        for bone, w in e[3].items():
            groups[bone].add([N_JOINTS + i], w, "REPLACE")

    mod = body.modifiers.new("armature", "ARMATURE")
    mod.object = arm_obj
    mod.use_vertex_groups = True
    body.modifiers.new("skin", "SKIN")
    skin = mesh.skin_vertices[0].data
    for j, name in enumerate(JOINT_NAMES):
        r = radii[joint_type(name)]
        skin[j].radius = (r, r)
    for i, e in enumerate(extra):
        skin[N_JOINTS + i].radius = (e[1], e[1])
    skin[JOINT_INDEX["pelvis"]].use_root = True
    if subdivision_levels > 0:
        sub = body.modifiers.new("subdivision", "SUBSURF")
        sub.levels = sub.render_levels = subdivision_levels
        # Catmull-Clark without the limit-surface projection: ~7x faster to evaluate and the
        # same kind of smooth body; both renderers use this evaluated mesh.
        sub.use_limit_surface = False
    return arm_obj, body


def pose_body(arm_obj, pose: Pose) -> None:
    """Pose the armature with ``pose``'s bone rotations and place it in the world (module docstring)."""
    import bpy
    from mathutils import Matrix

    bones = arm_obj.data.bones
    for name in BONES:
        Lr = bones[name].matrix_local.to_3x3()
        B = Lr.transposed() @ Matrix(np.asarray(pose.rotations[name]).tolist()) @ Lr
        arm_obj.pose.bones[name].matrix_basis = B.to_4x4()
    arm_obj.matrix_world = Matrix(np.asarray(pose.root).tolist())
    bpy.context.view_layer.update()


def evaluated_joints(arm_obj) -> np.ndarray:
    """(19, 3) posed joint positions in world metres, read from the evaluated armature."""
    import bpy

    dg = bpy.context.evaluated_depsgraph_get()
    ev = arm_obj.evaluated_get(dg)
    M = np.array(ev.matrix_world)
    out = np.zeros((N_JOINTS, 3))
    out[0] = np.array(ev.pose.bones["spine"].head)
    for c in range(1, N_JOINTS):
        out[c] = np.array(ev.pose.bones[JOINT_NAMES[c]].tail)
    return out @ M[:3, :3].T + M[:3, 3]


def evaluated_mesh(body) -> tuple[np.ndarray, np.ndarray]:
    """Blender's evaluated (posed, skinned, subdivided) body.

    Returns:
        vertices (V, 3) float64 world metres, triangles (T, 3) int32 vertex indices.
    """
    import bpy

    dg = bpy.context.evaluated_depsgraph_get()
    ev = body.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        me.calc_loop_triangles()
        nv, nt = len(me.vertices), len(me.loop_triangles)
        co = np.empty(nv * 3, np.float32)
        me.vertices.foreach_get("co", co)
        tris = np.empty(nt * 3, np.int32)
        me.loop_triangles.foreach_get("vertices", tris)
        M = np.array(ev.matrix_world)
    finally:
        ev.to_mesh_clear()
    v = co.reshape(-1, 3).astype(np.float64)
    return v @ M[:3, :3].T + M[:3, 3], tris.reshape(-1, 3)


@dataclass(frozen=True, eq=False)
class PosedMesh:
    """Blender's posed body, read back.

    Attributes:
        vertices: (V, 3) float64 evaluated (posed, skinned, subdivided) vertices, world metres.
        triangles: (T, 3) int32 vertex indices.
        joints: (19, 3) float64 posed joints of the evaluated armature, world metres.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    joints: np.ndarray


@contextlib.contextmanager
def posed_body(subject: dict, pose: Pose) -> Iterator[PosedMesh]:
    """Build ``subject``'s body, pose it, yield its geometry; the objects live until the block ends.

    Renders made inside the block see the body; its datablocks are deleted afterwards.
    """
    arm, body = build_body(subject)
    try:
        pose_body(arm, pose)
        vertices, triangles = evaluated_mesh(body)
        yield PosedMesh(vertices, triangles, evaluated_joints(arm))
    finally:
        delete_objects([body, arm])


def posed_mesh(subject: dict, pose: Pose) -> PosedMesh:
    """The geometry of ``subject``'s posed body; nothing is left in the Blender scene."""
    with posed_body(subject, pose) as mesh:
        return mesh


@contextlib.contextmanager
def quiet_stdout():
    """Send file descriptor 1 to /dev/null (Blender prints a 'Saved: ...' line per render)."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


def render_camera_png(cam, tmpdir: str | os.PathLike) -> Path:
    """Render the scene through Blender camera object ``cam`` to ``tmpdir/<cam.name>.png`` (the scene's
    file format settings), silencing Blender's per-render output; returns the path."""
    import bpy

    scene = bpy.context.scene
    path = Path(tmpdir) / f"{cam.name}.png"
    scene.camera = cam
    scene.render.filepath = str(path)
    with quiet_stdout():
        bpy.ops.render.render(write_still=True)
    return path


def render_masks(cameras: list, tmpdir: str | os.PathLike, threshold: float = 0.5, raw: bool = False) -> np.ndarray:
    """Render every camera with the scene's engine and read the silhouettes back.

    Args:
        cameras: camera objects from :func:`setup_scene`.
        tmpdir: scratch folder for the PNGs.
        raw: return the alpha channel as float32 in [0, 1] instead of a thresholded mask.
    Returns:
        (K, H, W) uint8 in {0, 1} (alpha > threshold), or float32 alpha if ``raw``.
    """
    out = []
    for cam in cameras:
        path = render_camera_png(cam, tmpdir)
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None or img.ndim != 3 or img.shape[2] != 4:
            raise RuntimeError(f"{path}: Blender did not write an RGBA render")
        alpha = img[..., 3].astype(np.float32) / 255.0
        out.append(alpha if raw else (alpha > threshold).astype(np.uint8))
    return np.stack(out)


def delete_objects(objects) -> None:
    """Remove objects and their data blocks (meshes, armatures, materials) and orphans."""
    import bpy

    datas = []
    for obj in objects:
        if obj is None:
            continue
        datas.append(obj.data)
        bpy.data.objects.remove(obj, do_unlink=True)
    for d in datas:
        if d is None:
            continue
        if isinstance(d, bpy.types.Mesh):
            mats = [m for m in d.materials if m is not None]
            bpy.data.meshes.remove(d, do_unlink=True)
            for m in mats:
                if m.users == 0:
                    bpy.data.materials.remove(m)
        elif isinstance(d, bpy.types.Armature):
            bpy.data.armatures.remove(d, do_unlink=True)
    for coll in (bpy.data.meshes, bpy.data.armatures, bpy.data.materials):
        for block in list(coll):
            if block.users == 0:
                coll.remove(block)


def add_spheres(centres: np.ndarray, radius: float) -> list:
    """UV spheres at ``centres`` (N, 3) world metres (calibration test targets)."""
    import bmesh
    import bpy

    objs = []
    for i, c in enumerate(np.asarray(centres, float)):
        mesh = bpy.data.meshes.new(f"sphere{i}")
        bm = bmesh.new()
        bmesh.ops.create_uvsphere(bm, u_segments=48, v_segments=24, radius=radius)
        bm.to_mesh(mesh)
        bm.free()
        obj = bpy.data.objects.new(f"sphere{i}", mesh)
        obj.location = c.tolist()
        bpy.context.scene.collection.objects.link(obj)
        objs.append(obj)
    bpy.context.view_layer.update()
    return objs


def render_sphere_targets(rig_dict: dict, centres, radius: float, engine: str = "workbench") -> np.ndarray:
    """Calibration check: render spheres at ``centres`` (N, 3) world metres, anti-aliased.

    Runs a fresh scene (factory settings). Returns the (K, H, W) float32 alpha of every rig
    camera; the intensity centroid of each sphere's blob should land on ``Camera.project`` of
    its centre.
    """
    rig = Rig.from_dict(rig_dict)
    reset_factory()
    cams = setup_scene(rig, engine, antialias=True)
    add_spheres(np.asarray(centres, float), radius)
    with tempfile.TemporaryDirectory(prefix="silpose-spheres-") as tmp:
        return render_masks(cams, tmp, raw=True)
