"""Test samples played on as short sequences of their own clip (``silpose eval``'s sequence experiment).

A lab records people moving, not lone frames, and ``silpose infer`` on a recording chooses among each frame's
hypotheses along the frames (:func:`silpose.model.hypotheses.temporal_choice`). A dataset's test split holds
lone frames, so it cannot measure that choice. This module plays test samples of a dataset posed by the procedural
walk or by the motion library (``[motion] source = "library"``) on as sequences:

- sample ``index``'s accepted draw is redrawn exactly as the dataset drew it (:func:`silpose.datagen.scene.draw_scene`
  with the sample's stored ``redraws``): its subject, gait or clip and mirror coin, heading and floor position;
- a library sample's clip is played through ``length`` consecutive library frames (the library's rate, 30 fps for
  the bundled one), from the sample's own frame, or earlier when the clip ends first (:func:`sequence_frames`); a
  walk sample walks on in place (a treadmill): its phase advances by ``1 / (WALK_FPS * CYCLE_S)`` per frame, the
  lab recording's cycle (:data:`silpose.datagen.lab.CYCLE_S`), at :data:`WALK_FPS` frames per second;
- every frame is rendered like a dataset sample (:func:`silpose.datagen.worker.make_record`). A frame whose person
  leaves an image is kept and marked (``visible`` False, or ``touches_border`` for a silhouette cut by the image's
  edge): a recording has such frames too, and the caller decides what to do with them.

:func:`dataset_worker_config` rebuilds the render workers' config from a dataset's stored config, so the sequences
are rendered by the dataset's own renderer, rig, placement and clips. :func:`render_sequences` runs in a spawned
worker (it imports bpy through the renderer; :func:`render_sequences_job` is its ``spawned_map`` entry);
:func:`render_sequences_spawned` is the driver that starts the workers. Nothing here imports bpy at module level.
"""

from __future__ import annotations

import numpy as np

from silpose.shared.camera import Rig

from .executor import WorkerDied, spawned_map
from .lab import CYCLE_S
from .motion.library import LibraryError, load_library
from .motion.mix import MixedMotion
from .motion.source import MotionSource, WalkMotion
from .render import rendering
from .renderers import renderer_from_config
from .scene import SampleScene, draw_scene
from .worker import check_worker_config, make_record, motion_from_config, placement_area

__all__ = ["WALK_FPS", "SequenceError", "dataset_worker_config", "sequence_frames", "sequence_params", "sequence_scenes",
           "render_sequences", "render_sequences_job", "render_sequences_spawned"]


#: frames per second of a walk sequence (a library clip's are the library's)
WALK_FPS = 30.0


class SequenceError(ValueError):
    """A dataset cannot be played as sequences (not a motion-library dataset, or its library changed)."""


def dataset_worker_config(config: dict, rig: Rig, source: str = "dataset config") -> dict:
    """The render workers' config (``GenConfig.worker_config``) of a walk or motion-library dataset, from its stored
    config.

    Args:
        config: the dataset's config as its manifest stores it (``GenConfig.to_dict``).
        rig: the dataset's cameras (``DatasetSplit.rig``).
        source: named in errors (e.g. the manifest's path).
    Raises:
        SequenceError: posed from BVH clips (``[motion] source = "bvh"``), or its library's frames file no longer has
            the checksum the dataset recorded, or a clip is no longer in it.
    """
    out = {key: config[key] for key in ("seed", "renderer", "blender_engine", "n_points", "max_redraws")}
    out["rig"] = rig.to_dict()
    if "placement" in config:
        out["placement"] = config["placement"]
    motion = config.get("motion")
    if motion is None:
        return out
    if motion.get("source") != "library":
        raise SequenceError(f"{source}: field 'motion.source' is {motion.get('source')!r}: sequences need a dataset "
                            "posed by the procedural walk or the motion library")
    lib_info = motion.get("library") or {}
    try:
        lib = load_library(lib_info.get("path"))
    except LibraryError as exc:
        raise SequenceError(f"{source}: field 'motion.library.path': {exc}") from None
    if lib.sha256() != lib_info.get("frames_sha256"):
        raise SequenceError(f"{source}: field 'motion.library.frames_sha256': the library at {lib.folder} has changed "
                            "since the dataset was generated")
    rows = {str(c["id"]): r for r, c in enumerate(lib.clips)}
    clips = []
    for c in motion.get("clips", [])[1:]:  # entry 0 is the procedural walk
        if str(c.get("id")) not in rows:
            raise SequenceError(f"{source}: field 'motion.clips': clip {c.get('id')!r} is not in the library at {lib.folder}")
        clips.append({"row": rows[str(c["id"])], "split": c["split"], "weight": float(c["weight"])})
    out["motion"] = {"source": "library", "library": str(lib.folder), "mirror": bool(motion.get("mirror", False)),
                     "procedural_walk": float(motion.get("procedural_walk", 0.0)),
                     "part_mix": float(motion.get("part_mix", 0.0)), "limb_swing": float(motion.get("limb_swing", 0.0)),
                     "limb_swing_deg": float(motion.get("limb_swing_deg", 90.0)), "clips": clips}
    return out


def sequence_frames(used: np.ndarray, frame: int, length: int) -> list[int]:
    """``length`` consecutive library frames of a clip (its BVH frame numbers ``used``, increasing) that hold
    ``frame``: from ``frame`` on, or ending at the clip's last frame when fewer than ``length`` follow it;
    the whole clip when it is shorter."""
    used = np.asarray(used, np.int64)
    k = int(np.searchsorted(used, frame))
    if k >= len(used) or used[k] != frame:
        raise ValueError(f"frame {frame} is not one of the clip's library frames")
    start = max(0, min(k, len(used) - int(length)))
    return [int(f) for f in used[start:start + int(length)]]


def sequence_params(first: dict[str, float], motion: MotionSource, length: int) -> list[dict[str, float]]:
    """The motion parameters of a sequence's frames, from its first draw's ``first`` (module docstring)."""
    if isinstance(motion, MixedMotion) and int(first["clip"]) > 0:
        used = motion.bvh.clips[motion.local[int(first["clip"])]].used
        return [dict(first, frame=float(f)) for f in sequence_frames(used, int(first["frame"]), length)]
    if isinstance(motion, (MixedMotion, WalkMotion)):
        step = 1.0 / (WALK_FPS * CYCLE_S)
        return [dict(first, phase=float((first["phase"] + t * step) % 1.0)) for t in range(int(length))]
    raise SequenceError(f"sequences need the procedural walk or library clips, not {type(motion).__name__}")


def sequence_scenes(seed: int, split: str, index: int, redraw: int, rig: Rig, motion: MotionSource,
                    length: int) -> list[SampleScene]:
    """The scenes of sample ``index``'s sequence (module docstring): its draw ``redraw``, frame by frame."""
    first = draw_scene(seed, split, index, redraw, rig, motion)
    return [SampleScene(split=split, index=int(index), redraw=int(redraw), subject=first.subject, motion=params,
                        pose=motion.pose(first.subject, params), rig=rig)
            for params in sequence_params(first.motion, motion, length)]


def render_sequences(config: dict, split: str, requests: list[tuple[int, int]], length: int) -> list[list[dict]]:
    """Render the sequences of ``requests`` ((sample index, its stored redraws) each) of ``split``.

    Returns one list of records per request, in order: :func:`silpose.datagen.worker.make_record`'s (the ``gait``
    field holds each frame's ``frame``) plus ``visible`` True; for a frame whose posed body leaves an image (the
    renderer returns no masks) or has no pixel in one, only ``visible`` False, ``joints`` (19, 3) and ``gait``.
    Imports bpy (through the renderer).
    """
    seed, rig, n_points, _ = check_worker_config(config)
    motion = motion_from_config(config, placement_area(config, rig), split)
    out = []
    with rendering(renderer_from_config(config), rig) as renderer:
        for index, redraw in requests:
            records = []
            for scene in sequence_scenes(seed, split, index, redraw, rig, motion, length):
                result = renderer.render(scene)
                masks = result.masks
                if masks is None or np.any(masks.reshape(len(rig), -1).max(axis=1) == 0):
                    records.append({"visible": False, "joints": np.asarray(result.joints, np.float32).reshape(-1, 3),
                                    "gait": {k: float(scene.motion[k]) for k in motion.fields}})
                    continue
                records.append({**make_record(scene, result, seed, n_points, motion.fields), "visible": True})
            out.append(records)
    return out


def render_sequences_job(message: tuple[dict, str, list, int]) -> tuple[list | None, str | None]:
    """``spawned_map`` entry: ``(render_sequences(*message), None)``, or ``(None, "<type>: <message>")``."""
    try:
        return render_sequences(*message), None
    except Exception as exc:  # noqa: BLE001 - reported by the driver
        return None, f"{type(exc).__name__}: {exc}"


def render_sequences_spawned(config: dict, split: str, requests: list[tuple[int, int]], length: int,
                             workers: int = 1) -> list[list[dict]]:
    """:func:`render_sequences` in ``workers`` spawned processes (the driver never imports bpy): the requests are
    dealt round-robin, the results returned in the requests' order.

    Raises:
        SequenceError: a worker raised (its error) or died (its exit code).
    """
    n = max(1, min(int(workers), len(requests)))
    chunks = [list(range(j, len(requests), n)) for j in range(n)]
    out: list = [None] * len(requests)
    jobs = [(j, (config, split, [requests[i] for i in chunk], int(length))) for j, chunk in enumerate(chunks) if chunk]
    try:
        for j, (result, error) in spawned_map(render_sequences_job, jobs, workers=n):
            if error is not None:
                raise SequenceError(f"rendering the {split} sequences failed: {error}")
            for i, records in zip(chunks[j], result):
                out[i] = records
    except WorkerDied as died:
        raise SequenceError(f"rendering the {split} sequences failed: {died}") from None
    return out
