"""Motion-capture benchmark: generation speed with poses from BVH clips vs the procedural walk.

Section ``motion`` of ``python -m benchmarks.run``. Both configs render the same number of samples
with the raster renderer in spawned workers through ``silpose.datagen.worker.render_samples`` (the
:mod:`benchmarks.generation` harness), same seed and rig; the BVH one adds the ``motion`` entry of a
prepared ``[motion] source = "bvh"`` config (clips memory-mapped from the import cache, retargeted
per sample). The ratio ``bvh_over_procedural`` (ms per sample) is the figure to compare (issue:
within 1.5x). The one-off import of the clips by Blender (into a fresh cache folder, timed) is its
own row. Clips: ``clips`` (globs of BVH files, e.g. public motion-capture clips kept outside the
repository) or, by default, the synthetic clip of ``silpose.datagen.testing`` (no third-party data).

A third config poses the bodies from the bundled motion library as the ``motions`` preset does
(``[motion] source = "library"``: the preset's groups, weights and procedural-walk share; no
Blender import): ``library_over_procedural`` is its ratio (issue: within 1.3x).
"""

from __future__ import annotations

import glob
import os
import tempfile
import time
from pathlib import Path

from silpose.datagen.config import load_config
from silpose.datagen.motion.clips import CACHE_ENV, prepare_motion
from silpose.datagen.motion.config import motion_from_dict
from silpose.datagen.testing import write_synthetic_bvh

from .generation import bench_config, run_pool


def run(n_samples: int = 200, processes: int = 1, clips: list[str] | None = None, scale: float = 0.01,
        synthetic_frames: int = 240, shard_size: int = 100, library_preset: str | None = "motions") -> list[dict]:
    """Measure the clips' import and ms per sample with BVH poses vs the walk.

    Args:
        n_samples: samples rendered per config.
        processes: worker processes per config (1: per-process speed).
        clips: BVH globs; default a synthetic clip of ``synthetic_frames`` frames (written here).
        scale: metres per BVH unit of ``clips`` (the synthetic clip is written in centimetres).
        library_preset: the preset whose ``[motion]`` library config is measured (None: skipped).
    Returns:
        rows ``{"name", "samples", "seconds", "samples_per_s", "ms_per_sample", "redraws"}`` for the
        walk and the clips (the latter with ``bvh_over_procedural``), and an ``import`` row
        (``clips``, ``frames``, ``seconds``).
    """
    with tempfile.TemporaryDirectory(prefix="silpose-bench-motion-") as tmp:
        tmp = Path(tmp)
        if clips:
            files = sorted({Path(h).resolve() for g in clips for h in glob.glob(g)})
            if not files:
                raise ValueError(f"clips {clips}: no BVH file matched")
        else:
            files = [write_synthetic_bvh(tmp / "synthetic.bvh", "cmu", unit=0.01, n_frames=synthetic_frames)]
        motion = motion_from_dict({"source": "bvh", "bvh": [str(f) for f in files], "scale": scale, "mirror": True},
                                  tmp, "benchmark")
        old = os.environ.get(CACHE_ENV)
        os.environ[CACHE_ENV] = str(tmp / "cache")  # a cold cache: the import is timed
        try:
            t0 = time.perf_counter()
            prepared = prepare_motion(motion, workers=processes)
            import_s = time.perf_counter() - t0
            rows = [{"name": "import (Blender, once per clip)", "clips": len(files),
                     "frames": sum(c.frames for c in prepared.clips), "seconds": import_s,
                     "ms_per_frame": 1000 * import_s / max(1, sum(c.frames for c in prepared.clips))}]
            warmup = 5
            speed = {}
            configs = [("procedural", bench_config("raster")),
                       ("bvh", {**bench_config("raster"), "motion": prepared.worker()})]
            if library_preset:
                lib = load_config(library_preset).with_motion().prepared
                configs.append(("library", {**bench_config("raster"), "motion": lib.worker()}))
            for name, cfg in configs:
                res = run_pool(cfg, n_samples, processes, shard_size, warmup)
                seconds = max(r["seconds"] for r in res)
                speed[name] = 1000 * seconds * processes / n_samples
                rows.append({"name": f"{name} raster x{processes}", "samples": n_samples, "seconds": seconds,
                             "samples_per_s": n_samples / seconds, "ms_per_sample": speed[name],
                             "redraws": sum(r["redraws"] for r in res)})
        finally:
            if old is None:
                os.environ.pop(CACHE_ENV, None)
            else:
                os.environ[CACHE_ENV] = old
    for row in rows[1:]:
        name = row["name"].split()[0]
        if name != "procedural":
            row[f"{name}_over_procedural"] = speed[name] / speed["procedural"]
    return rows
