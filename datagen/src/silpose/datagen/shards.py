"""Sharded, resumable generation into a locked folder: the machinery ``gen`` and ``gen-frames`` share.

A job is a list of :class:`executor.ShardTask` s, each a fixed index range of one split
(:func:`plan_split`), so the output does not depend on the number of workers, the executor or
interruptions. A run takes the folder's lock and deletes the temporaries of a killed run
(:func:`locked_folder`), skips the tasks whose outputs are complete (e.g. :func:`shard_is_complete`),
and runs the rest in spawned workers with a progress bar (:func:`run_tasks`), handing each result
to the caller as it arrives. Outputs are written under temporary names and renamed
(:mod:`silpose.shared.atomic`; docs/conventions.md, "Crash safety").
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from silpose.shared.atomic import TMP_GLOB
from silpose.shared.dataset import DatasetError, read_metadata, read_shard, shard_name
from silpose.shared.dataset_schema import ALL_COLUMNS
from silpose.shared.dataset_writer import restamp_shard

from .executor import DEFAULT_MAX_TASKS_PER_CHILD, EXECUTORS, ShardTask
from .manifest import FolderLock


class GenerationError(RuntimeError):
    """The output folder cannot be used or a shard could not be produced."""


def plan_split(split: str, count: int, shard_size: int) -> list[ShardTask]:
    """The shards of ``count`` samples of ``split``: ``{split}-{i:05d}-of-{n:05d}.parquet`` holds
    samples ``[i * shard_size, min(count, (i + 1) * shard_size))``."""
    n = math.ceil(count / shard_size)
    return [
        ShardTask(split, i, n, tuple(range(i * shard_size, min(count, (i + 1) * shard_size))), shard_name(split, i, n))
        for i in range(n)
    ]


def prepare_folder(out: Path) -> None:
    """Create ``out`` (and parents) or raise GenerationError naming it."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GenerationError(f"{out}: cannot create the output folder ({exc.strerror or exc})") from None
    if not out.is_dir():
        raise GenerationError(f"{out}: output path exists and is not a folder")
    probe = out / ".silpose-write-probe"
    try:
        probe.write_bytes(b"")
        probe.unlink(missing_ok=True)  # another run started at the same moment may have removed it first
    except OSError as exc:
        raise GenerationError(f"{out}: output folder is not writable ({exc.strerror or exc})") from None


def remove_temporaries(root: Path, recursive: bool = False) -> list[Path]:
    """Delete the temporary files (``silpose.shared.atomic.TMP_GLOB``) a killed run left in ``root``
    (and its subfolders if ``recursive``); call only while holding the folder's lock."""
    stale = list(root.rglob(TMP_GLOB) if recursive else root.glob(TMP_GLOB))
    for p in stale:
        p.unlink(missing_ok=True)
    return stale


@contextmanager
def locked_folder(out: Path, recursive: bool = False) -> Iterator[FolderLock]:
    """Create ``out``, hold its :class:`manifest.FolderLock` for the block, after deleting stale
    temporaries (:func:`remove_temporaries`). Yields the lock (``release()`` ends it early)."""
    prepare_folder(out)
    with FolderLock(out) as lock:
        remove_temporaries(out, recursive)
        yield lock


#: Config fields a finished shard does not depend on, so a rerun with another value keeps it (restamped with
#: the new config). ``max_redraws``: a sample is its first draw that every view sees whole, each draw a pure
#: function of (seed, split, index, redraw), so a sample found within 50 draws is the same with 1000 allowed
#: (a shard whose ``redraws`` exceed a lowered value is rendered again, and fails as this run would). ``train``:
#: ``silpose train``'s defaults (``[train]``), read after generation.
RESUME_NEUTRAL = ("max_redraws", "train")
#: ``[motion]`` augmentation fields whose value here draws and renders exactly what a config without the field
#: does (``silpose.datagen.motion.mix``): a dataset made before the field existed resumes under a config that
#: has it at this value.
MOTION_DEFAULTS = {"part_mix": 0.0, "limb_swing": 0.0}


def shard_is_complete(path: Path, task: ShardTask, metadata: dict) -> bool:
    """True if ``path`` is a readable shard of this config holding exactly ``task.indices``.

    Reads the whole shard through ``read_shard``, which verifies the schema, NaNs and every data
    page's checksum, so a shard with an intact footer but damaged data is rewritten, not kept (and
    hashed into the manifest). Raises GenerationError if the shard belongs to another configuration; a shard
    whose config differs only in :data:`RESUME_NEUTRAL` fields is kept and restamped with ``metadata``.
    """
    try:
        meta = read_metadata(path)
    except DatasetError:
        return False  # unreadable or foreign: it will be rewritten
    keys = ("config", "cameras", "transform", "workspace")
    if any(_resume_key(meta, k) != _resume_key(metadata, k) for k in keys):
        raise GenerationError(
            f"{path}: field 'config' differs from this run's; the folder holds another dataset "
            "(choose another --out or delete it)"
        )
    if meta["format_version"] != metadata["format_version"]:
        return False  # an older dataset format: rewritten in the current one
    try:
        shard = read_shard(path, columns=ALL_COLUMNS)
    except DatasetError:
        return False  # damaged data: it will be rewritten
    if not np.array_equal(shard.sample_id, np.asarray(task.indices)):
        return False
    if any(meta.get(k) != metadata.get(k) for k in keys):  # only RESUME_NEUTRAL fields differ
        limit = metadata["config"].get("max_redraws")
        if limit is not None and "redraws" in shard.extra and np.any(shard.extra["redraws"] > int(limit)):
            return False  # a sample took more redraws than this run allows: this run would fail it
        restamp_shard(path, metadata)  # one config in every shard of the folder (the readers check)
    return True


def _resume_key(metadata: dict, key: str):
    """``metadata[key]``, without the :data:`RESUME_NEUTRAL` fields for ``config``, nor its motion's
    :data:`MOTION_DEFAULTS` fields at their neutral value."""
    value = metadata.get(key)
    if key == "config" and isinstance(value, dict):
        value = {k: v for k, v in value.items() if k not in RESUME_NEUTRAL}
        motion = value.get("motion")
        if isinstance(motion, dict):
            value["motion"] = {k: v for k, v in motion.items() if MOTION_DEFAULTS.get(k, object()) != v}
    return value


def run_tasks(
    todo: list[ShardTask],
    worker_config: dict,
    target: str,
    on_result: Callable[[ShardTask, dict], None],
    *,
    sizes: dict[str, int],
    description: str,
    unit: str,
    executor: str = "local",
    workers: int | None = None,
    max_tasks_per_child: int = DEFAULT_MAX_TASKS_PER_CHILD,
    progress: bool = True,
) -> float:
    """Run ``todo`` in workers (``EXECUTORS[executor]``) and hand each result to ``on_result``.

    Args:
        todo: the tasks to run.
        worker_config: the dict every task receives.
        target: ``"module:function"`` run in the workers (``executor.run_task``).
        on_result: called in this process as ``on_result(task, result)`` when a task finishes
            (any order); it writes the task's outputs.
        sizes: progress units (samples, images) per task file.
        description, unit: progress bar label and unit name (rate shown in ``unit``/s).
        executor, workers, max_tasks_per_child: see :mod:`.executor`.
        progress: show a rich progress bar on stderr.
    Returns:
        wall seconds.
    """
    total = sum(sizes[t.file] for t in todo)
    done = 0
    t0 = time.perf_counter()
    columns = [
        TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
        TextColumn(f"{{task.fields[rate]:>7.2f}} {unit}/s"), TimeElapsedColumn(), TimeRemainingColumn(),
    ]
    with Progress(*columns, console=Console(stderr=True), disable=not progress or total == 0) as bar:
        job = bar.add_task(description, total=total, rate=0.0)
        results = EXECUTORS[executor](todo, worker_config, target, workers, max_tasks_per_child)
        try:
            for task, result in results:
                on_result(task, result)
                done += sizes[task.file]
                bar.update(job, advance=sizes[task.file], rate=done / max(time.perf_counter() - t0, 1e-9))
        finally:
            results.close()
    return time.perf_counter() - t0
