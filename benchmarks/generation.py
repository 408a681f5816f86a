"""Render benchmark: samples/s per process for each renderer, on all cores, and worker memory.

Section ``generation`` of ``python -m benchmarks.run``. Every measurement runs in SPAWNED worker
processes (this process never imports bpy), on the default rig (4 views, 320x240), through the
generator's worker entry point ``silpose.datagen.worker.render_samples``. Timings are wall-clock
and depend on the machine's load; the ratios (Blender's own render vs the raster renderer,
measured in the same run) are the figures to compare.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import time

import psutil

from silpose.datagen.worker import render_samples
from silpose.shared.camera import default_rig

RENDERERS = ("raster", "blender")


def bench_config(renderer: str, engine: str = "workbench", seed: int = 0) -> dict:
    """Generator config for a benchmark run (default rig, 200 contour points)."""
    return {
        "seed": seed,
        "renderer": renderer,
        "blender_engine": engine,
        "rig": default_rig().to_dict(),
        "n_points": 200,
        "max_redraws": 20,
    }


def worker_run(config: dict, split: str, start: int, n_samples: int, shard_size: int, warmup: int) -> dict:
    """Inside a spawned worker: render ``n_samples`` in shards, timing and sampling RSS.

    Returns:
        dict with ``n``, ``seconds`` (rendering only, after the warm-up shard), ``rss_mb``
        (RSS after the warm-up and after every shard, MiB), ``redraws``.
    """
    proc = psutil.Process(os.getpid())
    if warmup:
        render_samples(config, split, list(range(start - warmup, start)))
    rss = [proc.memory_info().rss / 2**20]
    redraws = 0
    t0 = time.perf_counter()
    for lo in range(start, start + n_samples, shard_size):
        recs = render_samples(config, split, list(range(lo, min(lo + shard_size, start + n_samples))))
        redraws += sum(r["redraws"] for r in recs)
        del recs  # the shard's records (~0.3 MiB of masks each) are the caller's, not growth
        rss.append(proc.memory_info().rss / 2**20)
    return {"n": n_samples, "seconds": time.perf_counter() - t0, "rss_mb": rss, "redraws": redraws}


def run_pool(config: dict, n_samples: int, processes: int, shard_size: int, warmup: int) -> list[dict]:
    ctx = mp.get_context("spawn")
    per = [n_samples // processes + (1 if i < n_samples % processes else 0) for i in range(processes)]
    starts = [warmup + sum(per[:i]) for i in range(processes)]
    with ctx.Pool(processes) as pool:
        jobs = [
            pool.apply_async(worker_run, (config, "train", starts[i], per[i], shard_size, warmup))
            for i in range(processes)
        ]
        return [j.get() for j in jobs]


def run(
    n_samples: int = 200,
    renderers: tuple[str, ...] = RENDERERS,
    engine: str = "workbench",
    processes: int | None = None,
    memory_samples: int = 1000,
    shard_size: int = 100,
) -> list[dict]:
    """Measure generation speed and worker memory.

    For each renderer: ``n_samples`` in one worker process (samples/s per process), then the
    same number split over ``processes`` workers started together (all cores by default;
    aggregate samples/s over the slowest worker's time). Then ``memory_samples`` samples with
    the first renderer in one worker, RSS sampled inside the worker after every shard of
    ``shard_size`` (each shard starts with a factory reset, as in ``gen``).

    Returns:
        list of rows ``{"name", "renderer", "processes", "samples", "seconds",
        "samples_per_s", "ms_per_sample", "rss_start_mb", "rss_end_mb", "rss_growth_mb"}``;
        the speed rows of the non-raster renderers carry ``"raster_speedup"``.
    """
    processes = processes or os.cpu_count() or 1
    rows: list[dict] = []
    warmup = 5
    for renderer in renderers:
        cfg = bench_config(renderer, engine)
        for nproc in sorted({1, processes}):
            res = run_pool(cfg, n_samples, nproc, shard_size, warmup)
            seconds = max(r["seconds"] for r in res)
            rows.append(
                {
                    "name": f"{renderer}{'/' + engine if renderer == 'blender' else ''} x{nproc}",
                    "renderer": renderer,
                    "processes": nproc,
                    "samples": n_samples,
                    "seconds": seconds,
                    "samples_per_s": n_samples / seconds,
                    "ms_per_sample": 1000 * seconds * nproc / n_samples,
                    "rss_start_mb": max(r["rss_mb"][0] for r in res),
                    "rss_end_mb": max(r["rss_mb"][-1] for r in res),
                    "rss_growth_mb": max(r["rss_mb"][-1] - r["rss_mb"][0] for r in res),
                    "redraws": sum(r["redraws"] for r in res),
                }
            )
    raster = {r["processes"]: r for r in rows if r["renderer"] == "raster"}
    for r in rows:
        if r["renderer"] != "raster" and r["processes"] in raster:
            r["raster_speedup"] = r["ms_per_sample"] / raster[r["processes"]]["ms_per_sample"]
    if memory_samples:
        renderer = renderers[0]
        res = run_pool(bench_config(renderer, engine), memory_samples, 1, shard_size, warmup)[0]
        rows.append(
            {
                "name": f"memory {renderer} x1",
                "renderer": renderer,
                "processes": 1,
                "samples": memory_samples,
                "seconds": res["seconds"],
                "samples_per_s": memory_samples / res["seconds"],
                "ms_per_sample": 1000 * res["seconds"] / memory_samples,
                "rss_start_mb": res["rss_mb"][0],
                "rss_end_mb": res["rss_mb"][-1],
                "rss_growth_mb": res["rss_mb"][-1] - res["rss_mb"][0],
                "rss_curve_mb": [round(v, 1) for v in res["rss_mb"]],
                "redraws": res["redraws"],
            }
        )
    return rows
