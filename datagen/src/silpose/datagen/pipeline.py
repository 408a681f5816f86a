"""Generate a dataset folder: plan shards, skip complete ones, render the rest, write the manifest.

Sample ``i`` of a split is a pure function of ``(seed, split, i)`` (computed by the renderer), and a
shard holds the fixed index range ``[i * shard_size, (i + 1) * shard_size)``, so the data do not
depend on the number of workers, the executor or on interruptions: a rerun into the same folder
verifies the shards already there (footer row count, sample ids, config) and renders only the
missing ones. Shards are written under a temporary name and renamed; stale temporaries from a
killed run are deleted first. A lock file keeps two runs out of one folder. The planning, resume,
lock and worker loop are :mod:`.shards` (shared with ``gen-frames``).
"""

from __future__ import annotations

import time
from pathlib import Path

import pyarrow.parquet as pq

from silpose.shared.atomic import write_json_atomic
from silpose.shared.dataset import SHARD_RE, build_metadata, write_shard
from silpose.shared.seeds import MOTION_STREAM

from .card import write_card
from .character_sheet import write_characters
from .config import GenConfig
from .executor import DEFAULT_MAX_TASKS_PER_CHILD, DEFAULT_RENDER, EXECUTORS, ShardTask, default_workers
from .manifest import MANIFEST, MANIFEST_VERSION, sha256_file
from .preview import write_preview
from .shards import GenerationError, locked_folder, plan_split, run_tasks, shard_is_complete


def plan_shards(config: GenConfig) -> list[ShardTask]:
    """All shards of the dataset, ``{split}-{i:05d}-of-{n:05d}.parquet``, in split then index order."""
    return [t for split, count in config.splits.items() for t in plan_split(split, count, config.shard_size)]


def dataset_metadata(config: GenConfig) -> dict:
    """The schema metadata of every shard of ``config``'s dataset (``silpose.shared.dataset.build_metadata``)."""
    rig = config.rig.to_dict()  # transform / workspace only when they differ from the defaults
    return build_metadata(rig["cameras"], config.to_dict(), config.n_points,
                          rig_frame={k: rig[k] for k in ("transform", "workspace") if k in rig})


def _check_records(records: list[dict], task: ShardTask) -> None:
    ids = [r.get("sample_id") for r in records]
    if ids != list(task.indices) or any(r.get("split") != task.split for r in records):
        raise GenerationError(
            f"shard {task.file}: field 'sample_id': renderer returned ids {ids[:3]}... for split "
            f"{records[0].get('split') if records else '?'}, expected {list(task.indices[:3])}... of {task.split}"
        )


def generate(
    config: GenConfig,
    out: str | Path,
    workers: int | None = None,
    executor: str = "local",
    render: str = DEFAULT_RENDER,
    progress: bool = True,
    max_tasks_per_child: int = DEFAULT_MAX_TASKS_PER_CHILD,
    preview: bool = False,
    card: bool = False,
) -> dict:
    """Generate (or complete) the dataset of ``config`` in ``out``; returns the manifest.

    Args:
        config: a validated config (``load_config``).
        out: dataset folder (created).
        workers: worker processes (default: all cores; with Ray, the CPUs of the running cluster).
        executor: ``"local"`` (spawn pool) or ``"ray"``.
        render: ``"module:function"`` with the signature of ``worker.render_samples``.
        progress: show a rich progress bar (samples/s) on stderr.
        max_tasks_per_child: shard tasks per worker process before it is replaced.
        preview, card: also write ``preview.png`` and the dataset card ``README.md`` (under the lock).
    """
    if executor not in EXECUTORS:
        raise GenerationError(f"executor: must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    out = Path(out)
    if executor == "local":
        workers = workers or default_workers()
    config = config.with_motion(workers=workers)  # motion-capture clips: imported once, cached
    with locked_folder(out):
        metadata = dataset_metadata(config)
        tasks = plan_shards(config)
        planned = {t.file for t in tasks}
        foreign = sorted(p.name for p in out.iterdir() if SHARD_RE.match(p.name) and p.name not in planned)
        if foreign:
            raise GenerationError(
                f"{out / foreign[0]}: shard of another configuration (this config plans "
                f"{tasks[0].file} ...); choose another --out or delete the folder"
            )
        todo = [t for t in tasks if not ((out / t.file).exists() and shard_is_complete(out / t.file, t, metadata))]
        for t in todo:
            (out / t.file).unlink(missing_ok=True)
        stats = _run(todo, config, out, metadata, workers, executor, render, progress, max_tasks_per_child)
        manifest = build_manifest(config, out, tasks, stats, workers, executor, skipped=len(tasks) - len(todo))
        write_json_atomic(out / MANIFEST, manifest)
        if preview:
            write_preview(out)
            write_characters(out)
        if card:
            write_card(out)
    return manifest


def _run(todo, config, out, metadata, workers, executor, render, progress, max_tasks_per_child) -> dict:
    """Render ``todo``, writing each shard as it arrives; returns the timing statistics."""
    stats = {"seconds": 0.0, "samples": 0, "worker_seconds": 0.0, "worker_rss_mb": {}, "shard_seconds": {}}

    def write(task: ShardTask, result: dict) -> None:
        records = result["records"]
        _check_records(records, task)
        write_shard(out / task.file, records, metadata)
        stats["samples"] += len(records)
        stats["worker_seconds"] += result["seconds"]
        stats["shard_seconds"][task.file] = round(result["seconds"], 3)
        stats["worker_rss_mb"].setdefault(str(result["pid"]), []).append(round(result["rss_mb"], 1))

    stats["seconds"] = run_tasks(
        todo, config.worker_config(), render, write, sizes={t.file: len(t.indices) for t in todo},
        description=f"gen {config.name}", unit="samples", executor=executor, workers=workers,
        max_tasks_per_child=max_tasks_per_child, progress=progress,
    )
    return stats


def build_manifest(config: GenConfig, out: Path, tasks, stats: dict, workers: int, executor: str, skipped: int) -> dict:
    """The manifest of a complete dataset folder (hashes every shard)."""
    shards, redraws = [], {s: 0 for s in config.splits}
    for t in tasks:
        path = out / t.file
        r = pq.read_table(path, columns=["redraws"]).column("redraws").to_numpy()
        redraws[t.split] += int(r.sum())
        shards.append({
            "file": t.file, "split": t.split, "rows": len(t.indices),
            "sample_ids": [t.indices[0], t.indices[-1]], "redraws": int(r.sum()),
            "bytes": path.stat().st_size, "sha256": sha256_file(path),
        })
    rate = stats["samples"] / stats["seconds"] if stats["seconds"] > 0 else None
    return {
        "manifest_version": MANIFEST_VERSION,
        "name": config.name,
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "config": config.to_dict(),
        "seeds": {
            "dataset_seed": config.seed,
            "rule": "sample i of split s is a pure function of (dataset_seed, s, i): draw r uses numpy SeedSequence([dataset_seed, split_code, i, r]) with split_code train=0, test=1; rejected draws are counted in redraws",
            **({"motion_rule": f"motion-capture draws (clip, frame, mirror, heading, x, y) use SeedSequence([{MOTION_STREAM}, dataset_seed, split_code, i, r])"}
               if config.motion.uses_clips else {}),
        },
        "counts": dict(config.splits),
        "redraws": redraws,
        "shards": shards,
        "timing": {
            "executor": executor, "workers": workers, "shards_rendered": len(tasks) - skipped,
            "shards_skipped": skipped, "samples_rendered": stats["samples"],
            "wall_seconds": round(stats["seconds"], 3), "samples_per_second": round(rate, 2) if rate else None,
            "worker_seconds": round(stats["worker_seconds"], 3), "worker_rss_mb": stats["worker_rss_mb"],
        },
    }
