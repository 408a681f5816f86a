"""Benchmark of the whole ``silpose gen`` pipeline: local spawn pool vs Ray, same config and data.

Each run generates the same dataset (a preset with its split sizes overridden) into a fresh temporary
folder with :func:`silpose.datagen.pipeline.generate` -- shards, manifest, resume checks included --
and reports samples/s; the Ray run starts (and stops) a local Ray instance with the same number of
CPUs, so its startup cost is part of the figure, as it is for a user. The Ray row's ratio is against
the local run measured in the same call. Both datasets' arrays are compared: they must be identical.
Section ``pipeline`` of ``python -m benchmarks.run``.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from silpose.datagen.config import load_config
from silpose.datagen.pipeline import generate
from silpose.shared.dataset import load_split


def _arrays(root: Path):
    s = load_split(root, "train")
    return s.sample_id, s.joints, s.contours


def run(n_samples: int = 400, workers: int = 2, executors=("local", "ray"), preset: str = "default",
        shard_size: int = 50) -> list[dict]:
    """Rows ``{"name", "executor", "workers", "samples", "seconds", "samples_per_s", "identical_to_local"}``
    (Ray rows add ``"vs_local"``: samples/s ratio against the local run)."""
    config = load_config(preset, shard_size=shard_size, splits={"train": int(n_samples), "test": 0})
    rows, ref = [], None
    with tempfile.TemporaryDirectory(prefix="silpose-bench-gen-") as tmp:
        for ex in executors:
            out = Path(tmp) / ex
            t0 = time.perf_counter()
            if ex == "ray":
                os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
                import ray

                ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
                try:
                    generate(config, out, workers=workers, executor="ray", progress=False)
                finally:
                    ray.shutdown()
            else:
                generate(config, out, workers=workers, executor=ex, progress=False)
            seconds = time.perf_counter() - t0
            arrays = _arrays(out)
            same = None if ref is None else all(np.array_equal(a, b) for a, b in zip(arrays, ref))
            ref = ref if ref is not None else arrays
            rows.append({"name": f"gen {preset} {ex} x{workers}", "executor": ex, "workers": workers,
                         "samples": int(n_samples), "seconds": seconds, "samples_per_s": n_samples / seconds,
                         "identical_to_local": same})
    local = next((r for r in rows if r["executor"] == "local"), None)
    for r in rows:
        if local is not None and r is not local:
            r["vs_local"] = r["samples_per_s"] / local["samples_per_s"]
    return rows
