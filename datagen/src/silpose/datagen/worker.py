"""Render one shard of samples inside a spawned worker process (the driver never imports bpy).

Every sample is a pure function of ``(config["seed"], split, index)``: draw ``redraw`` of it is
:func:`scene.draw_scene` (``derive_rng(seed, SPLIT_CODE[split], index, redraw)``;
docs/conventions.md, "Seeds"). A draw whose person is not fully inside every image is rejected
and redrawn with ``redraw + 1``: first from the pose's forward-kinematics joints (cheap, before
Blender builds anything), then from Blender's posed mesh projected with the rig (the renderer
returns no masks), and last from the rendered masks (empty, or touching the image border).
``redraws`` counts the rejected draws. The renderer is the registry's entry for
``config["renderer"]`` (:mod:`.renderers`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from silpose.shared.camera import Rig
from silpose.shared.contours import extract_contours, normalise
from silpose.shared.seeds import SPLIT_CODE
from silpose.shared.skeleton import N_JOINTS

from .motion.bvh_motion import BvhMotion
from .motion.mix import MixedMotion
from silpose.shared.rig_frame import DEFAULT_WORKSPACE, Workspace

from .motion.source import WALK, MotionSource, WalkMotion
from .render import RenderResult, Renderer, rendering
from .renderers import MASK_RENDERERS, renderer_from_config
from .scene import SampleScene, draw_scene, joints_visible
from .subjects import SUBJECT_FIELDS


class SampleError(RuntimeError):
    """A sample could not be produced (e.g. no visible draw within ``max_redraws``)."""


def check_worker_config(config: dict) -> tuple[int, Rig, int, int]:
    """``(seed, rig, n_points, max_redraws)`` of a worker config; KeyError/ValueError name the field."""
    for key in ("seed", "renderer", "rig", "n_points", "max_redraws"):
        if key not in config:
            raise KeyError(f"config: missing field {key!r}")
    if config["renderer"] not in MASK_RENDERERS:
        raise ValueError(f"config field renderer: must be one of {MASK_RENDERERS}, got {config['renderer']!r}")
    rig = Rig.from_dict(config["rig"], source="config field rig")
    n_points, max_redraws = int(config["n_points"]), int(config["max_redraws"])
    if n_points < 3:
        raise ValueError(f"config field n_points: must be >= 3, got {n_points}")
    if max_redraws < 0:
        raise ValueError(f"config field max_redraws: must be >= 0, got {max_redraws}")
    return int(config["seed"]), rig, n_points, max_redraws


def motion_from_config(config: dict, workspace: Workspace = DEFAULT_WORKSPACE, split: str = "train") -> MotionSource:
    """The worker config's motion source on ``workspace`` (the rig's): the walk, ``BvhMotion`` for
    a ``motion`` entry of BVH clips, ``MixedMotion`` (the ``split``'s library clips and the walk)
    for a motion library."""
    motion = config.get("motion")
    if motion is None:
        return WalkMotion(workspace)
    if motion.get("source") == "library":
        return MixedMotion.from_config(motion, split, workspace)
    if motion.get("source") != "bvh":
        raise ValueError(f"config field motion.source: must be 'bvh' or 'library' in a worker config, got {motion.get('source')!r}")
    return BvhMotion.from_config(motion, workspace)


def placement_area(config: dict, rig: Rig) -> Workspace:
    """Where the worker config's walkers are placed: its ``placement`` (the part of the rig's workspace every
    camera sees, ``GenConfig.placement``), else the rig's workspace."""
    return Workspace.from_dict(config["placement"]) if "placement" in config else rig.workspace


def make_record(scene: SampleScene, result: RenderResult, seed: int, n_points: int,
                fields: tuple[str, ...] | None = None) -> dict[str, Any]:
    """Assemble one output record (see :func:`render_samples`) from a scene and its masks.

    ``fields``: the motion parameters stored in the ``gait`` column (default: all of ``scene.motion``).
    """
    masks = result.masks
    c = extract_contours(masks, n_points)
    _, centroid, scale = normalise(c["points"])
    return {
        "sample_id": int(scene.index),
        "split": scene.split,
        "seed": int(seed),
        "redraws": int(scene.redraw),
        "subject": {k: float(scene.subject[k]) for k in SUBJECT_FIELDS},
        "gait": {k: float(scene.motion[k]) for k in (fields or tuple(scene.motion))},
        "joints": np.asarray(result.joints, np.float32).reshape(N_JOINTS, 3),
        "masks": masks.astype(np.uint8),
        "contours": c["points"].astype(np.float32),
        "contour_centroid": centroid.astype(np.float32),
        "contour_scale": scale.astype(np.float32),
        "touches_border": c["touches_border"].astype(bool),
        "n_blobs": c["n_blobs"].astype(np.int32),
        "contour_length": c["length"].astype(np.float32),
        "area": c["area"].astype(np.int32),
    }


def render_sample(renderer: Renderer, seed: int, split: str, index: int, rig: Rig, n_points: int,
                  max_redraws: int, motion: MotionSource = WALK) -> dict[str, Any]:
    """The record of sample ``index`` of ``split``: its first fully visible draw (module docstring).

    ``renderer`` must be open on ``rig``. Raises SampleError after ``max_redraws + 1`` rejected draws.
    """
    for redraw in range(max_redraws + 1):
        scene = draw_scene(seed, split, index, redraw, rig, motion)
        if not joints_visible(scene):
            continue
        result = renderer.render(scene)
        if result.masks is None or np.any(result.masks.reshape(len(rig), -1).max(axis=1) == 0):
            continue
        rec = make_record(scene, result, seed, n_points, motion.fields)
        if np.any(rec["touches_border"]):
            continue
        return rec
    raise SampleError(
        f"{split} sample {index} (seed {seed}): no draw fully visible in every view after "
        f"{max_redraws + 1} draws (config field max_redraws)"
    )


def render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Render samples ``indices`` of ``split`` ("train" or "test") -- one shard.

    Pure function of ``(config["seed"], split, index)`` per sample. Imports bpy (only here, through
    the renderer's Blender adapter).

    Args:
        config: ``seed`` (int), ``renderer`` ("raster" | "blender"), ``blender_engine``
            ("workbench" | "cycles", blender renderer only), ``rig`` (``Rig.to_dict()``),
            ``n_points`` (contour points), ``max_redraws``, optionally ``motion`` (motion-capture
            clips, :meth:`clips.PreparedMotion.worker`; default the walk cycle) and ``placement`` (a
            ``Workspace`` dict: where walkers are placed; default the rig's workspace).
        split: "train" or "test".
        indices: sample indices.
    Returns:
        one dict per index, in order: ``sample_id``, ``split``, ``seed``, ``redraws``,
        ``subject`` (SUBJECT_FIELDS), ``gait`` (the motion source's fields: ``walk.GAIT_FIELDS``
        or ``clips.BVH_FIELDS``), ``joints`` (19, 3) float32 world
        metres, ``masks`` (K, H, W) uint8 {0,1}, ``contours`` (K, n, 2) float32 px,
        ``contour_centroid`` (K, 2), ``contour_scale`` (K,), ``touches_border`` (K,) bool,
        ``n_blobs`` (K,) int32, ``contour_length`` (K,) float32, ``area`` (K,) int32.
    Raises:
        SampleError: no fully visible draw within ``max_redraws`` redraws.
    """
    if split not in SPLIT_CODE:
        raise ValueError(f"split must be one of {tuple(SPLIT_CODE)}, got {split!r}")
    seed, rig, n_points, max_redraws = check_worker_config(config)
    motion = motion_from_config(config, placement_area(config, rig), split)
    with rendering(renderer_from_config(config), rig) as renderer:
        return [render_sample(renderer, seed, split, index, rig, n_points, max_redraws, motion) for index in indices]
