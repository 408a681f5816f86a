"""Render textured camera frames inside a spawned worker (the driver never imports bpy).

One task renders either the empty room (``split == "background"``) or a shard of test samples
(``split == "test"``). A person frame uses exactly the scene, camera and Cycles settings (same
sampling seed) of the empty-room render, with the person added, so the room pixels the person
does not affect (by occlusion, shadow or bounce light) have the same clean values in both.

The truth of a sample is ``worker.render_samples(config, "test", indices)``'s record -- the
record ``silpose gen`` writes for test sample i -- and the person mesh is re-posed from the same
draw (``draw_sample_parameters(seed, "test", i, record["redraws"])``); the worker checks that
Blender's posed joints equal the record's and, for the raster renderer, that the mesh fills the
record's masks exactly.
"""

from __future__ import annotations

import tempfile
import time

import numpy as np

from silpose.shared.camera import Rig

from . import frames_scene as fs
from .worker import draw_sample_parameters, render_samples


class FramesRenderError(RuntimeError):
    """The textured render disagrees with the truth record (a bug, never expected)."""


def _frames_options(config: dict) -> tuple[int, bool]:
    f = config.get("frames")
    if not isinstance(f, dict) or "cycles_samples" not in f or "denoise" not in f:
        raise KeyError("config: missing field 'frames' with 'cycles_samples' and 'denoise'")
    return int(f["cycles_samples"]), bool(f["denoise"])


def render_empty_room(config: dict) -> dict:
    """Clean render of the empty room in every camera.

    Args:
        config: ``GenConfig.worker_config()`` plus ``frames`` (``cycles_samples``, ``denoise``).
    Returns:
        ``{"empty": (K, H, W, 3) float32 RGB display levels 0..255, "image_seconds": [s per image]}``.
    """
    from . import blender_room as br

    samples, denoise = _frames_options(config)
    rig = Rig.from_dict(config["rig"])
    cams = br.setup_cycles(rig, samples, denoise)
    br.build_room(rig)
    with tempfile.TemporaryDirectory(prefix="silpose-frames-") as tmp:
        t0 = time.perf_counter()
        empty = br.render_rgb(cams, tmp)
        dt = time.perf_counter() - t0
    return {"empty": empty, "image_seconds": [dt / len(cams)] * len(cams)}


def render_person_frames(config: dict, indices: list[int]) -> dict:
    """Truth records and clean textured renders of test samples ``indices``.

    Returns:
        ``{"records": render_samples' records (list, in order), "frames": (n, K, H, W, 3) float32
        RGB display levels 0..255, "appearance": [draw_appearance dicts], "image_seconds": [...]}``.
    """
    from . import blender_room as br
    from . import blender_scene as bs
    from .raster import project_vertices, rasterize_projected
    from .walk import posed_body, root_transform

    samples, denoise = _frames_options(config)
    seed = int(config["seed"])
    rig = Rig.from_dict(config["rig"])
    W, H = rig.image_size
    records = render_samples(config, "test", list(indices))
    cams = br.setup_cycles(rig, samples, denoise)
    br.build_room(rig)
    frames, looks, seconds = [], [], []
    with tempfile.TemporaryDirectory(prefix="silpose-frames-") as tmp:
        for rec in records:
            i = rec["sample_id"]
            subject, gait = draw_sample_parameters(seed, "test", i, rec["redraws"])
            posed = posed_body(subject, gait)
            root = root_transform(subject, gait, posed)
            arm, body = bs.build_body(subject)
            try:
                bs.pose_body(arm, subject, gait, root)
                vertices, triangles = bs.evaluated_mesh(body)
                joints = bs.evaluated_joints(arm)
            finally:
                bs.delete_objects([body, arm])
            if not np.array_equal(joints.astype(np.float32), rec["joints"]):
                raise FramesRenderError(f"test sample {i}: posed joints differ from the truth record's")
            if config["renderer"] == "raster":
                masks = rasterize_projected(project_vertices(vertices, rig, min_depth=0.05), triangles, H, W)
                if not np.array_equal(masks, rec["masks"]):
                    raise FramesRenderError(f"test sample {i}: the person mesh does not fill the truth masks")
            look = fs.draw_appearance(seed, i)
            labels = fs.part_labels(vertices, triangles, joints, fs.joint_radius_array(subject), look)
            person = br.add_person(vertices, triangles, labels, look)
            try:
                t0 = time.perf_counter()
                frames.append(br.render_rgb(cams, tmp))
                seconds += [(time.perf_counter() - t0) / len(cams)] * len(cams)
            finally:
                bs.delete_objects([person])
            looks.append(look)
    return {"records": records, "frames": np.stack(frames), "appearance": looks, "image_seconds": seconds}


def render_frames_task(config: dict, split: str, indices: list[int]) -> dict:
    """Executor entry point (``executor.run_local`` target): ``split`` "background" renders the
    empty room (``indices`` empty), "test" renders the samples ``indices``."""
    if split == "background":
        return render_empty_room(config)
    if split == "test":
        return render_person_frames(config, indices)
    raise ValueError(f"split must be 'background' or 'test', got {split!r}")
