"""Render textured camera frames inside a spawned worker (the driver never imports bpy).

One task renders either the empty room (``split == "background"``) or a shard of test samples
(``split == "test"``), with the ``textured`` renderer (:class:`.render.TexturedRenderer`).

The truth of a sample is ``worker.render_samples(config, "test", indices)``'s record -- the
record ``silpose gen`` writes for test sample i -- and the textured scene is the same draw
(``draw_scene(seed, "test", i, record["redraws"])``) dressed by :func:`.scene.draw_appearance`;
the worker checks that Blender's posed joints equal the record's and, for the raster renderer,
that the mesh fills the record's masks exactly.
"""

from __future__ import annotations

import numpy as np

from silpose.shared.camera import Rig

from ..render import rendering
from ..scene import draw_scene
from ..worker import motion_from_config, placement_area, render_samples
from .render import TexturedRenderer
from .scene import draw_appearance


class FramesRenderError(RuntimeError):
    """The textured render disagrees with the truth record (a bug, never expected)."""


def render_empty_room(config: dict) -> dict:
    """Clean render of the empty room in every camera.

    Args:
        config: ``GenConfig.worker_config()`` plus ``frames`` (``cycles_samples``, ``denoise``).
    Returns:
        ``{"empty": (K, H, W, 3) float32 RGB display levels 0..255, "image_seconds": [s per image]}``.
    """
    rig = Rig.from_dict(config["rig"])
    with rendering(TexturedRenderer.from_config(config), rig) as renderer:
        empty, seconds = renderer.render_empty()
    return {"empty": empty, "image_seconds": [seconds / len(rig)] * len(rig)}


def render_person_frames(config: dict, indices: list[int]) -> dict:
    """Truth records and clean textured renders of test samples ``indices``.

    Returns:
        ``{"records": render_samples' records (list, in order), "frames": (n, K, H, W, 3) float32
        RGB display levels 0..255, "appearance": [draw_appearance dicts], "image_seconds": [...]}``.
    """
    seed = int(config["seed"])
    rig = Rig.from_dict(config["rig"])
    renderer = TexturedRenderer.from_config(config)  # checks the frames options before any render
    records = render_samples(config, "test", list(indices))
    motion = motion_from_config(config, placement_area(config, rig), "test")  # the walk, or the motion-capture clips
    frames, looks, seconds = [], [], []
    with rendering(renderer, rig):
        for rec in records:
            i = rec["sample_id"]
            scene = draw_scene(seed, "test", i, rec["redraws"], rig, motion, appearance=draw_appearance(seed, i))
            result = renderer.render(scene)
            if not np.array_equal(result.joints.astype(np.float32), rec["joints"]):
                raise FramesRenderError(f"test sample {i}: posed joints differ from the truth record's")
            if config["renderer"] == "raster" and not np.array_equal(result.masks, rec["masks"]):
                raise FramesRenderError(f"test sample {i}: the person mesh does not fill the truth masks")
            frames.append(result.images)
            seconds += [result.seconds / len(rig)] * len(rig)
            looks.append(scene.appearance)
    return {"records": records, "frames": np.stack(frames), "appearance": looks, "image_seconds": seconds}


def render_frames_task(config: dict, split: str, indices: list[int]) -> dict:
    """Executor entry point (``executor.run_local`` target): ``split`` "background" renders the
    empty room (``indices`` empty), "test" renders the samples ``indices``."""
    if split == "background":
        return render_empty_room(config)
    if split == "test":
        return render_person_frames(config, indices)
    raise ValueError(f"split must be 'background' or 'test', got {split!r}")
