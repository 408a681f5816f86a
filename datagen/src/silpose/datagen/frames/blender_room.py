"""The Blender adapter for textured camera frames in Cycles: the room, its props and lights, the
clothed person (bpy).

Like :mod:`silpose.datagen.blender.scene`, bpy is imported lazily inside the functions: call them only in a
spawned worker whose parent never imported bpy. The layout and colours come from
:mod:`.frames.scene` (pure numpy).

The person is the same evaluated (posed, skinned, subdivided) body mesh the raster renderer
fills for the truth masks (``blender.scene.evaluated_mesh``), copied into a static mesh with one
material per garment, so the rendered person and the true silhouette are the same geometry.
"""

from __future__ import annotations

import os

import cv2
import numpy as np

from silpose.shared.camera import Rig

from ..blender.scene import render_camera_png, reset_factory, setup_scene
from . import scene as fs


def setup_cycles(rig: Rig, samples: int, denoise: bool) -> list:
    """Fresh scene, one camera per rig camera, Cycles CPU path tracing to 16-bit RGB PNG.

    Args:
        samples: Cycles samples per pixel (fixed seed, no adaptive sampling).
        denoise: use the OpenImageDenoise denoiser (CPU).
    Returns:
        the camera objects in rig order.
    """
    import bpy

    reset_factory()
    cams = setup_scene(rig, "cycles")
    scene = bpy.context.scene
    r = scene.render
    r.film_transparent = False
    r.image_settings.color_mode = "RGB"
    r.image_settings.color_depth = "16"
    r.threads_mode = "FIXED"
    r.threads = 1  # one render thread per worker process: the pool provides the parallelism
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    c = scene.cycles
    c.samples = int(samples)
    c.use_adaptive_sampling = False
    c.seed = 0
    c.use_animated_seed = False
    c.max_bounces = 3
    c.diffuse_bounces = 2
    c.glossy_bounces = 0
    c.transmission_bounces = 0
    c.volume_bounces = 0
    c.transparent_max_bounces = 0
    c.caustics_reflective = c.caustics_refractive = False
    c.pixel_filter_type = "BLACKMAN_HARRIS"
    c.filter_width = 1.5
    c.use_denoising = bool(denoise)
    if denoise:
        c.denoiser = "OPENIMAGEDENOISE"
        c.denoising_input_passes = "RGB_ALBEDO_NORMAL"
    return cams


def _material(name: str, colour, roughness: float = 0.8):
    import bpy

    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Specular IOR Level"].default_value = 0.2
    return m, bsdf


def _mix_by_texture(m, bsdf, colour_a, colour_b, texture: str, scale: float, **params) -> None:
    """Base colour = mix of two colours by a procedural texture of world coordinates."""
    nodes, links = m.node_tree.nodes, m.node_tree.links
    coord = nodes.new("ShaderNodeNewGeometry")  # world position (objects are scaled boxes)
    tex = nodes.new(texture)
    tex.inputs["Scale"].default_value = scale
    for k, v in params.items():
        if k in tex.inputs:
            tex.inputs[k].default_value = v
        else:
            setattr(tex, k, v)
    links.new(coord.outputs["Position"], tex.inputs["Vector"])
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.inputs["A"].default_value = (*colour_a, 1.0)
    mix.inputs["B"].default_value = (*colour_b, 1.0)
    fac = tex.outputs["Fac"]
    if texture == "ShaderNodeTexNoise":  # noise Fac stays near 0.5: stretch [0.3, 0.7] to [0, 1]
        stretch = nodes.new("ShaderNodeMapRange")
        stretch.inputs["From Min"].default_value, stretch.inputs["From Max"].default_value = 0.3, 0.7
        stretch.clamp = True
        links.new(fac, stretch.inputs["Value"])
        fac = stretch.outputs["Result"]
    links.new(fac, mix.inputs["Factor"])
    links.new(mix.outputs["Result"], bsdf.inputs["Base Color"])


def _add_grain(m, bsdf, scale: float, amount: float) -> None:
    """Multiply the base colour by a cellular grain: Voronoi cells of ``scale`` per metre (a few
    pixels at 7 m), each with a random factor in ``[1 - amount, 1 + amount]`` (terrazzo-like texture
    at the scale the background subtraction's shadow test correlates on)."""
    nodes, links = m.node_tree.nodes, m.node_tree.links
    base = bsdf.inputs["Base Color"].links[0].from_socket
    coord = nodes.new("ShaderNodeNewGeometry")  # world position (objects are scaled boxes)
    tex = nodes.new("ShaderNodeTexVoronoi")
    tex.inputs["Scale"].default_value = scale
    links.new(coord.outputs["Position"], tex.inputs["Vector"])
    bw = nodes.new("ShaderNodeRGBToBW")
    links.new(tex.outputs["Color"], bw.inputs["Color"])
    stretch = nodes.new("ShaderNodeMapRange")
    stretch.inputs["To Min"].default_value, stretch.inputs["To Max"].default_value = 1.0 - amount, 1.0 + amount
    links.new(bw.outputs["Val"], stretch.inputs["Value"])
    mul = nodes.new("ShaderNodeMix")
    mul.data_type = "RGBA"
    mul.blend_type = "MULTIPLY"
    mul.inputs["Factor"].default_value = 1.0
    links.new(base, mul.inputs["A"])
    links.new(stretch.outputs["Result"], mul.inputs["B"])
    links.new(mul.outputs["Result"], bsdf.inputs["Base Color"])


def _box_object(name: str, centre, size, material):
    import bmesh
    import bpy

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = tuple(float(v) for v in centre)
    obj.scale = tuple(float(v) for v in size)
    mesh.materials.append(material)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def build_room(rig: Rig) -> list[dict]:
    """Floor, four walls, the props of :func:`frames.scene.place_props`, a sun and ambient light.

    Returns:
        the placed props (for the card).
    """
    import bpy
    from mathutils import Vector

    half, h = fs.room_half_size(rig), fs.ROOM_HEIGHT
    cx, cy = (float(v) for v in fs.room_centre(rig))  # the workspace's centre
    floor_m, bsdf = _material("floor", fs.FLOOR_COLOURS[0], roughness=0.6)
    _mix_by_texture(floor_m, bsdf, *fs.FLOOR_COLOURS, "ShaderNodeTexNoise", 6.0, Detail=6.0, Roughness=0.7)
    _add_grain(floor_m, bsdf, fs.FLOOR_GRAIN["scale"], fs.FLOOR_GRAIN["amount"])
    wall_m, bsdf = _material("wall", fs.WALL_COLOUR, roughness=0.9)
    _mix_by_texture(wall_m, bsdf, fs.WALL_COLOUR, tuple(0.8 * c for c in fs.WALL_COLOUR), "ShaderNodeTexNoise",
                    1.5, Detail=3.0)
    t = 0.1
    _box_object("floor", (cx, cy, -t / 2), (2 * half, 2 * half, t), floor_m)
    for name, c, s in (
        ("wall_px", (cx + half + t / 2, cy, h / 2), (t, 2 * half, h)),
        ("wall_nx", (cx - half - t / 2, cy, h / 2), (t, 2 * half, h)),
        ("wall_py", (cx, cy + half + t / 2, h / 2), (2 * half, t, h)),
        ("wall_ny", (cx, cy - half - t / 2, h / 2), (2 * half, t, h)),
    ):
        _box_object(name, c, s, wall_m)
    props = fs.place_props(rig)
    for p in props:
        m, _ = _material(p["name"], p["colour"], roughness=0.7)
        for i, (bc, bsz) in enumerate(p["boxes"]):
            _box_object(f"{p['name']}{i}", bc, bsz, m)

    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = fs.SUN["strength"]
    sun.angle = np.deg2rad(fs.SUN["angle_deg"])
    obj = bpy.data.objects.new("sun", sun)
    d = fs.sun_direction()  # the light shines along -d; Blender's sun shines along its local -z
    obj.rotation_euler = Vector(tuple(d)).to_track_quat("Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(obj)
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = fs.AMBIENT
    bpy.context.scene.world = world
    bpy.context.view_layer.update()
    return props


def add_person(vertices: np.ndarray, triangles: np.ndarray, labels: np.ndarray, appearance: dict):
    """A static mesh of the posed body (world metres) with one material per garment (``labels``
    index :data:`frames.scene.PARTS`); the shirt gets horizontal stripes if ``stripe_period`` > 0."""
    import bpy

    mesh = bpy.data.meshes.new("person")
    mesh.from_pydata([tuple(v) for v in np.asarray(vertices, float)], [], [tuple(t) for t in np.asarray(triangles)])
    mesh.update()
    for part in fs.PARTS:
        m, bsdf = _material(f"person_{part}", appearance[part], roughness=0.9 if part != "shoes" else 0.4)
        if part == "shirt" and appearance["stripe_period"] > 0:
            _mix_by_texture(m, bsdf, appearance["shirt"], appearance["stripe"], "ShaderNodeTexWave",
                            1.0 / appearance["stripe_period"], wave_type="BANDS", bands_direction="Z",
                            Distortion=0.0)
        mesh.materials.append(m)
    mesh.polygons.foreach_set("material_index", np.asarray(labels, np.int32))
    mesh.polygons.foreach_set("use_smooth", np.ones(len(mesh.polygons), bool))
    obj = bpy.data.objects.new("person", mesh)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    return obj


def render_rgb(cameras: list, tmpdir: str | os.PathLike) -> np.ndarray:
    """Render every camera; returns (K, H, W, 3) float32 RGB display levels in [0, 255]
    (read from 16-bit PNGs, so quantisation to 8 bits happens only after the noise is added)."""
    out = []
    for cam in cameras:
        path = render_camera_png(cam, tmpdir)
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None or img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint16:
            raise RuntimeError(f"{path}: Blender did not write a 16-bit RGB render")
        out.append(img[..., ::-1].astype(np.float32) * (255.0 / 65535.0))
    return np.stack(out)
