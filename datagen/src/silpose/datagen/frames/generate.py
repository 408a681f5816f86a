"""Write a "frames dataset": textured camera frames of test samples, empty-room frames, truth.

Layout (the contract with the end-to-end path; ``<camera>`` = the rig camera's name)::

    <dir>/rig.json                       Rig.to_dict() as JSON
    <dir>/background/<camera>/00000.png  N empty-room RGB frames per camera (noise + flicker)
    <dir>/frames/<camera>/00000.png      frame i = test sample i, one per camera (noise + flicker)
    <dir>/test-00000-of-0000n.parquet    truth: silhouette dataset split "test" (write_shard),
                                         record i = test sample i of ``silpose gen``
    <dir>/README.md                      the card
    <dir>/.silpose-frames.json           the configuration of the run (for resume checks)
    <dir>/.silpose-output.json           the output marker (silpose.shared.output_dir), written first

Atomicity: the dataset is built in ``<parent>/.<name>.partial/`` and renamed to ``<dir>`` when
complete, so ``<dir>`` is either absent or whole. Every file is written under a temporary name
and renamed (:mod:`silpose.shared.atomic`); a task's PNGs are written before its truth shard, so a
shard on disk marks its samples done. A rerun resumes the partial folder of the same
configuration (refuses another), and reports an existing complete ``<dir>`` of the same
configuration as done (refuses another). Planning, lock, resume and the worker loop are
:mod:`silpose.datagen.shards`, shared with ``silpose gen``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np

from silpose.shared.atomic import write_bytes_atomic, write_json_atomic, write_text_atomic
from silpose.shared.camera_noise import add_camera_noise, noise_rng
from silpose.shared.dataset import write_shard
from silpose.shared.output_dir import MARKER, claim_folder

from ..config import GenConfig
from ..executor import ShardTask
from ..manifest import LOCK
from ..pipeline import dataset_metadata
from ..shards import locked_folder, plan_split, run_tasks, shard_is_complete
from .card import write_frames_card
from .config import FramesConfig
from .scene import SCENE_VERSION

TARGET = "silpose.datagen.frames.worker:render_frames_task"
IDENTITY = ".silpose-frames.json"
LAYOUT_VERSION = 1


class FramesError(RuntimeError):
    """The output folder cannot be used (another dataset, unwritable) or a task failed."""


def frame_name(i: int) -> str:
    return f"{i:05d}.png"


def plan_tasks(fcfg: FramesConfig) -> list[ShardTask]:
    """The empty-room task, then one task (= one truth shard) per ``shard_size`` samples."""
    return [ShardTask("background", 0, 1, (), "background")] + plan_split("test", fcfg.samples, fcfg.shard_size)


def write_png(path: Path, rgb: np.ndarray) -> None:
    """(H, W, 3) uint8 RGB -> PNG at ``path``, atomically (``silpose.shared.atomic``)."""
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]))
    if not ok:
        raise FramesError(f"{path}: PNG encoding failed")
    write_bytes_atomic(path, buf.tobytes())


def _identity(config: GenConfig, fcfg: FramesConfig) -> dict:
    return {"layout_version": LAYOUT_VERSION, "scene_version": SCENE_VERSION, "config": config.to_dict(),
            "frames": fcfg.to_dict()}


def read_identity(root: Path) -> dict | None:
    """The run configuration recorded in ``root/.silpose-frames.json`` (IDENTITY), or None."""
    try:
        return json.loads((root / IDENTITY).read_text())
    except (OSError, json.JSONDecodeError):
        return None


def _is_partial_frames(work: Path) -> bool:
    """An unfinished frames folder of a run from before output markers: it has the IDENTITY file, or
    only the lock (killed before writing anything)."""
    return read_identity(work) is not None or all(p.name == LOCK for p in work.iterdir())


def _task_done(work: Path, task: ShardTask, cams: list[str], fcfg: FramesConfig, metadata: dict) -> bool:
    if task.split == "background":
        return all((work / "background" / c / frame_name(j)).is_file() for c in cams for j in range(fcfg.background))
    if not all((work / "frames" / c / frame_name(i)).is_file() for c in cams for i in task.indices):
        return False
    return (work / task.file).is_file() and shard_is_complete(work / task.file, task, metadata)


def _write_result(work: Path, task: ShardTask, result: dict, cams: list[str], config: GenConfig,
                  fcfg: FramesConfig, metadata: dict) -> int:
    """Noise + flicker on the clean renders, PNGs, then the truth shard. Returns images written."""
    sigma, flicker = fcfg.noise_sigma, fcfg.flicker
    if task.split == "background":
        empty = result["empty"]
        for k, cam in enumerate(cams):
            for j in range(fcfg.background):
                write_png(work / "background" / cam / frame_name(j),
                          add_camera_noise(empty[k], noise_rng(config.seed, "background", k, j), sigma, flicker))
        return len(cams) * fcfg.background
    records, frames = result["records"], result["frames"]
    ids = [r["sample_id"] for r in records]
    if ids != list(task.indices) or frames.shape[0] != len(ids):
        raise FramesError(f"task {task.file}: worker returned samples {ids}, expected {list(task.indices)}")
    for s, i in enumerate(ids):
        for k, cam in enumerate(cams):
            write_png(work / "frames" / cam / frame_name(i),
                      add_camera_noise(frames[s, k], noise_rng(config.seed, "frames", k, i), sigma, flicker))
    write_shard(work / task.file, records, metadata)
    return len(ids) * len(cams)


def generate_frames(
    config: GenConfig, fcfg: FramesConfig, out: str | Path, workers: int | None = None, progress: bool = True,
    target: str = TARGET,
) -> dict:
    """Build (or resume, or find complete) the frames dataset of ``config`` + ``fcfg`` at ``out``.

    Args:
        config: the preset's generator config (seed, rig, renderer of the truth, n_points).
        fcfg: the ``[frames]`` section.
        out: the dataset folder (must not hold anything else).
        workers: spawned worker processes (default: all cores).
        progress: rich progress bar (images/s) on stderr.
        target: ``"module:function"`` run in the workers (``frames.worker.render_frames_task``).
    Returns:
        summary: ``out``, ``already_complete``, ``images_written``, ``seconds``, ``image_seconds``
        (Cycles render wall time per image, list), ``tasks_rendered``, ``tasks_skipped``.
    """
    out = Path(out)
    config = config.with_motion(workers=workers)  # motion-capture clips: imported once, cached
    identity = _identity(config, fcfg)
    if out.exists():
        if out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        elif read_identity(out) == identity:
            return {"out": str(out), "already_complete": True, "images_written": 0, "seconds": 0.0,
                    "image_seconds": [], "tasks_rendered": 0, "tasks_skipped": len(plan_tasks(fcfg))}
        else:
            what = "another frames dataset" if read_identity(out) is not None else "files that are not this frames dataset"
            raise FramesError(f"{out}: exists and holds {what}; choose another --out or delete it")
    work = out.parent / f".{out.name}.partial"
    cams = list(config.rig.names)
    metadata = dataset_metadata(config)
    claim_folder(work, "gen-frames", recognise=_is_partial_frames)  # before the cleanup of temporaries
    with locked_folder(work, recursive=True) as lock:
        found = read_identity(work)
        if found is None and any(p.name not in (lock.path.name, MARKER) for p in work.iterdir()):
            raise FramesError(f"{work}: unfinished folder without {IDENTITY}; delete it and rerun")
        if found is not None and found != identity:
            raise FramesError(f"{work}: unfinished run of another configuration (field 'frames' or 'config' "
                              "differs); delete it or rerun with the same options")
        write_json_atomic(work / IDENTITY, identity)
        write_text_atomic(work / "rig.json", config.rig.to_json())
        for sub in ("background", "frames"):
            for c in cams:
                (work / sub / c).mkdir(parents=True, exist_ok=True)
        tasks = plan_tasks(fcfg)
        todo = [t for t in tasks if not _task_done(work, t, cams, fcfg, metadata)]
        stats = _run(todo, config, fcfg, work, cams, metadata, workers, progress, target)
        write_frames_card(work, config, fcfg, stats)
        lock.release()
    os.rename(work, out)  # the whole folder at once: <out> is absent or complete
    return {"out": str(out), "already_complete": False, **stats, "tasks_rendered": len(todo),
            "tasks_skipped": len(tasks) - len(todo)}


def _run(todo, config, fcfg, work, cams, metadata, workers, progress, target) -> dict:
    """Render ``todo``, writing each task's PNGs and truth shard as it arrives."""
    stats = {"images_written": 0, "seconds": 0.0, "image_seconds": []}

    def write(task: ShardTask, result: dict) -> None:
        stats["images_written"] += _write_result(work, task, result["records"], cams, config, fcfg, metadata)
        stats["image_seconds"] += list(result["records"]["image_seconds"])

    worker_config = dict(config.worker_config(), frames={"cycles_samples": fcfg.cycles_samples, "denoise": fcfg.denoise})
    sizes = {t.file: (fcfg.background if t.split == "background" else len(t.indices)) * len(cams) for t in todo}
    stats["seconds"] = run_tasks(
        todo, worker_config, target, write, sizes=sizes, description=f"gen-frames {config.name}", unit="images",
        workers=workers, progress=progress,
    )
    return stats
