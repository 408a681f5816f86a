"""The renderer interface: scene description, motion seam, registry, the worker's use of the
protocol (with a pure-numpy stand-in renderer), and the two mask renderers compared on the same
scenes through the protocol (Blender, in a SPAWNED worker; this process never imports bpy)."""

from __future__ import annotations

import dataclasses
import multiprocessing as mp
import sys

import cv2
import numpy as np
import pytest

from silpose.datagen.config import ConfigError, load_config
from silpose.datagen.frames.render import TexturedRenderer
from silpose.datagen.motion import BONES, WALK, MotionSource, Pose
from silpose.datagen.render import RenderResult, Renderer, rendering
from silpose.datagen.renderers import (
    MASK_RENDERERS,
    RENDERERS,
    BlenderRenderer,
    RasterRenderer,
    UnknownRendererError,
    get_renderer,
    renderer_from_config,
)
from silpose.datagen.scene import SampleScene, draw_scene, joints_visible
from silpose.datagen.testing import render_scenes_with
from silpose.datagen.walk import skeleton_positions
from silpose.datagen.worker import SampleError, check_worker_config, render_sample
from silpose.shared.camera import default_rig, ring_rig
from silpose.shared.seeds import SPLIT_CODE
from silpose.shared.skeleton import N_JOINTS

RIG = default_rig()
TIMEOUT_S = 300


def _config(renderer="raster", **kw):
    return {"seed": 11, "renderer": renderer, "blender_engine": "workbench", "rig": RIG.to_dict(), "n_points": 64,
            "max_redraws": 20, **kw}


# -- scene description and motion seam (pure) -------------------------------------------------

def test_scene_is_a_frozen_pure_function_of_its_keys():
    a, b = draw_scene(3, "test", 5, 2, RIG), draw_scene(3, "test", 5, 2, RIG)
    assert a.subject == b.subject and a.motion == b.motion
    np.testing.assert_array_equal(a.pose.joints, b.pose.joints)
    np.testing.assert_array_equal(a.pose.root, b.pose.root)
    other = draw_scene(3, "train", 5, 2, RIG)
    assert other.motion != a.motion
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.redraw = 0
    assert "bpy" not in sys.modules


def test_walk_pose_is_the_forward_kinematics_of_its_rotations():
    """Pose.joints equals walk.skeleton_positions; a chain rebuilt from Pose.rotations and the root
    (an independent forward-kinematics loop) gives the same joints."""
    from silpose.datagen.walk import rest_skeleton
    from silpose.shared.skeleton import JOINT_NAMES, PARENTS

    scene = draw_scene(0, "train", 4, 0, RIG)
    pose = scene.pose
    assert isinstance(WALK, MotionSource) and isinstance(pose, Pose)
    assert set(pose.rotations) == set(BONES) and len(BONES) == N_JOINTS - 1
    for R in pose.rotations.values():
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(pose.joints, skeleton_positions(scene.subject, scene.motion), atol=1e-12)
    rest = rest_skeleton(scene.subject)
    G, J = {0: np.eye(3)}, {0: rest[0]}
    for c in range(1, N_JOINTS):
        p = PARENTS[c]
        G[c] = G[p] @ pose.rotations[JOINT_NAMES[c]]
        J[c] = J[p] + G[c] @ (rest[c] - rest[p])
    world = np.array([J[c] for c in range(N_JOINTS)]) @ pose.root[:3, :3].T + pose.root[:3, 3]
    np.testing.assert_allclose(world, pose.joints, atol=1e-12)
    # feet on the floor: the lowest joint is within an ankle height of z = 0
    assert -1e-9 < pose.joints[:, 2].min() < 0.12


def test_sample_stream_keys_are_seed_split_index_redraw():
    ref = np.random.default_rng(np.random.SeedSequence([3, 1, 5, 2]))
    from silpose.datagen.scene import sample_rng

    np.testing.assert_array_equal(sample_rng(3, "test", 5, 2).uniform(size=6), ref.uniform(size=6))
    assert SPLIT_CODE == {"train": 0, "test": 1}
    with pytest.raises(ValueError, match="split"):
        draw_scene(3, "validation", 0, 0, RIG)


# -- registry ------------------------------------------------------------------------------------

def test_registry_maps_names_to_protocol_classes():
    assert set(RENDERERS) == {"raster", "blender", "textured"}
    assert MASK_RENDERERS == ("raster", "blender")
    for name, cls in RENDERERS.items():
        assert cls.name == name and get_renderer(name) is cls
        assert isinstance(cls(), Renderer)
    assert isinstance(renderer_from_config(_config("raster")), RasterRenderer)
    blender = renderer_from_config(_config("blender", blender_engine="cycles"))
    assert isinstance(blender, BlenderRenderer) and blender.engine == "cycles"
    textured = renderer_from_config(_config(frames={"cycles_samples": 4, "denoise": False}), "textured")
    assert isinstance(textured, TexturedRenderer) and (textured.samples, textured.denoise) == (4, False)


def test_registry_rejects_unknown_names_clearly():
    with pytest.raises(UnknownRendererError) as err:
        get_renderer("eevee")
    assert str(err.value) == "config field renderer: unknown renderer 'eevee'; known: raster, blender, textured"
    assert isinstance(err.value, ValueError)
    with pytest.raises(UnknownRendererError, match="'eevee'"):
        renderer_from_config(_config("eevee"))
    with pytest.raises(ValueError, match="blender_engine"):
        renderer_from_config(_config("blender", blender_engine="eevee"))
    with pytest.raises(KeyError, match="frames"):
        renderer_from_config(_config(), "textured")


def test_datasets_accept_only_mask_renderers(tmp_path):
    with pytest.raises(ValueError, match="renderer: must be one of"):
        check_worker_config(_config("textured"))
    with pytest.raises(ConfigError, match="field 'renderer' must be one of raster, blender"):
        load_config("smoke", renderer="textured")


def test_renderers_refuse_a_scene_of_another_rig():
    other = ring_rig(n_cameras=2, focal_px=235.0, width=160, height=120)
    r = RasterRenderer()
    with pytest.raises(ValueError, match="before open"):
        r.render(draw_scene(0, "train", 0, 0, RIG))
    r.rig = RIG  # opened without Blender (open() would start a Blender session)
    with pytest.raises(ValueError, match="rig"):
        r.render(draw_scene(0, "train", 0, 0, other))


# -- the worker drives any Renderer --------------------------------------------------------------

class DiscRenderer:
    """A pure-numpy stand-in: discs at the projected joints; the first draw of every sample is
    reported as leaving the image (masks None), so the worker must redraw."""

    name = "discs"

    def __init__(self):
        self.opened = self.closed = 0
        self.rendered: list[tuple[int, int]] = []

    def open(self, rig):
        self.opened += 1
        self.rig = rig

    def close(self):
        self.closed += 1

    def render(self, scene: SampleScene) -> RenderResult:
        self.rendered.append((scene.index, scene.redraw))
        if scene.redraw == 0:
            return RenderResult(joints=scene.pose.joints, masks=None)
        W, H = scene.rig.image_size
        masks = np.zeros((len(scene.rig), H, W), np.uint8)
        for k, cam in enumerate(scene.rig):
            for x, y in np.rint(cam.project(scene.pose.joints)).astype(int):
                cv2.circle(masks[k], (int(x), int(y)), 6, 1, -1)
        return RenderResult(joints=scene.pose.joints, masks=masks)


def test_worker_renders_through_the_protocol_and_redraws():
    fake = DiscRenderer()
    assert isinstance(fake, Renderer)
    with rendering(fake, RIG):
        recs = [render_sample(fake, 11, "train", i, RIG, 64, 20) for i in (0, 1)]
    assert (fake.opened, fake.closed) == (1, 1)
    for i, rec in enumerate(recs):
        assert rec["sample_id"] == i and rec["redraws"] >= 1
        scene = draw_scene(11, "train", i, rec["redraws"], RIG)
        assert joints_visible(scene) and (i, rec["redraws"]) in fake.rendered
        np.testing.assert_array_equal(rec["joints"], scene.pose.joints.astype(np.float32))
        assert rec["contours"].shape == (len(RIG), 64, 2) and rec["masks"].sum() > 0
    with pytest.raises(SampleError, match="max_redraws"):
        render_sample(DiscRenderer(), 11, "train", 0, RIG, 64, 0)


def test_rendering_closes_on_errors():
    fake = DiscRenderer()
    with pytest.raises(RuntimeError):
        with rendering(fake, RIG):
            raise RuntimeError("boom")
    assert (fake.opened, fake.closed) == (1, 1)


# -- the two mask renderers on the same scenes (Blender) -----------------------------------------

@pytest.mark.blender
def test_mask_renderers_agree_through_the_protocol():
    with mp.get_context("spawn").Pool(1) as pool:
        out = pool.apply_async(render_scenes_with, (_config(), ["raster", "blender"], "train", [0, 1, 2])).get(TIMEOUT_S)
    ious = []
    for r, b in zip(out["raster"], out["blender"]):
        assert r["redraw"] == b["redraw"]
        np.testing.assert_array_equal(r["joints"], b["joints"])  # the same body, built once per renderer
        assert r["masks"].shape == b["masks"].shape == (len(RIG), *RIG.image_size[::-1])
        for k in range(len(RIG)):
            a, c = r["masks"][k].astype(bool), b["masks"][k].astype(bool)
            assert a.any()
            ious.append((a & c).sum() / (a | c).sum())
    print(f"raster vs workbench through the protocol: IoU min {min(ious):.4f}")
    assert len(ious) == 3 * len(RIG) and min(ious) >= 0.99
    assert "bpy" not in sys.modules
