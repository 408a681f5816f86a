"""Benchmark: peak memory (RSS) of the in-memory vs the streaming (out-of-core) MPPCA fit.

    python -m silpose.model.bench_memory --data data/default --repeat 1,2,4
    python -m silpose.model.bench_memory --data data/paper --repeat 1,2,4 --modes stream

Each measurement runs in its own Python subprocess: it imports everything, records its RSS
(``baseline``), fits the shape+structure model on the dataset's train split, and reports the
process's peak RSS (``getrusage`` ``ru_maxrss``, exact, not sampled). ``fit`` = peak - baseline.

``--repeat k`` makes the dataset k times larger *for this measurement only*: the in-memory fit
concatenates k copies of the split's arrays, the streaming fit reads the same shard files k times
per pass (a k-fold longer list of shards, same shard size). The trainer itself has no such option.
Memory does not depend on the number of EM iterations (each is one pass over the same data), so the
default ``--max-iter 2`` keeps the runs short; the hyperparameters default to M 5, q 60 (pass -M/-q for the model defaults, M 20, q 40).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

_MARK = "@@MEMORY@@"


def _repeated(source, k: int):
    """``source`` (DatasetShards) reading its shard files ``k`` times per pass (measurement only)."""
    return replace(source, paths=source.paths * k, n_rows=source.n_rows * k, rows=source.rows * k)


def measure(mode: str, data: str, repeat: int, n_components: int, n_latent: int, max_iter: int) -> dict:
    """Child side: fit once and return {mode, repeat, n_rows, d, shard_rows, baseline_mb, peak_mb, fit_mb, seconds}."""
    import resource
    import time
    import warnings

    import numpy as np
    import psutil
    import pyarrow.parquet  # noqa: F401  (imported before the baseline)
    import sklearn.cluster  # noqa: F401
    from sklearn.exceptions import ConvergenceWarning

    from silpose.shared.dataset import load_split
    from silpose.model.shape_model import ShapeStructureModel
    from silpose.model.streaming import DatasetShards

    warnings.simplefilter("ignore", ConvergenceWarning)
    plan = DatasetShards.open(data, "train")
    baseline = psutil.Process().memory_info().rss
    model = ShapeStructureModel(n_components, n_latent, n_init=1, max_iter=max_iter, tol=0.0, random_state=0)
    t0 = time.perf_counter()
    if mode == "memory":
        split = load_split(data, "train", columns=["joints", "contours"])
        c, j = split.contours, split.joints
        if repeat > 1:
            c, j = np.concatenate([c] * repeat), np.concatenate([j] * repeat)
        model.fit(c, j, rig=split.rig)
    elif mode == "stream":
        model.fit_shards(_repeated(plan, repeat))
    else:
        raise ValueError(f"mode must be 'memory' or 'stream', got {mode!r}")
    seconds = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux: kilobytes
    mb = 2.0**-20
    return {"mode": mode, "repeat": repeat, "n_rows": int(model.n_train_), "d": int(model.layout_.dim),
            "shard_rows": max(plan.n_rows), "features_mb": model.n_train_ * model.layout_.dim * 8 * mb,
            "baseline_mb": baseline * mb, "peak_mb": peak * mb, "fit_mb": (peak - baseline) * mb,
            "em_iterations": int(model.mixture_.n_iter_), "seconds": seconds}


def run_memory_bench(data: str = "data/default", repeats=(1, 2, 4), modes=("memory", "stream"),
                     n_components: int = 5, n_latent: int = 60, max_iter: int = 2,
                     missing_ok: bool = False) -> list[dict]:
    """One subprocess per (mode, repeat); rows as ``measure`` returns them, plus the ratio of each
    streaming fit's memory to the in-memory fit's at the same size (``fit_mb_vs_memory``) when both ran.
    A missing ``data`` folder raises, or with ``missing_ok`` gives one row saying it was not measured."""
    if not Path(data).is_dir():
        if missing_ok:
            return [{"mode": "not measured", "reason": f"{data} not found (generate it with silpose gen)"}]
        raise FileNotFoundError(f"{data}: dataset folder not found (generate it with silpose gen)")
    rows = []
    for repeat in repeats:
        for mode in modes:
            args = json.dumps([mode, str(data), int(repeat), n_components, n_latent, max_iter])
            code = (f"import json, sys; from silpose.model.bench_memory import measure; "
                    f"print({_MARK!r} + json.dumps(measure(*json.loads(sys.argv[1]))))")
            proc = subprocess.run([sys.executable, "-c", code, args], capture_output=True, text=True)
            lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(_MARK)]
            if proc.returncode != 0 or not lines:
                tail = " | ".join((proc.stderr or proc.stdout).strip().splitlines()[-3:])
                raise RuntimeError(f"bench_memory: {mode} x{repeat} failed (exit {proc.returncode}): {tail}")
            rows.append(json.loads(lines[-1][len(_MARK):]))
    by_key = {(r["mode"], r["repeat"]): r for r in rows}
    for r in rows:
        ref = by_key.get(("memory", r["repeat"]))
        if r["mode"] == "stream" and ref is not None:
            r["fit_mb_vs_memory"] = r["fit_mb"] / ref["fit_mb"] if ref["fit_mb"] > 0 else float("nan")
    return rows


def to_markdown(rows: list[dict]) -> str:
    lines = ["| mode | repeat | rows | d | shard rows | features MB | baseline MB | peak MB | fit MB | s |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['mode']} | {r['repeat']}x | {r['n_rows']} | {r['d']} | {r['shard_rows']} | "
                     f"{r['features_mb']:.0f} | {r['baseline_mb']:.0f} | {r['peak_mb']:.0f} | {r['fit_mb']:.0f} | "
                     f"{r['seconds']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m silpose.model.bench_memory", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", default="data/default", help="dataset folder (its train split is fitted)")
    p.add_argument("--repeat", default="1,2,4", help="comma-separated dataset multipliers (measurement only)")
    p.add_argument("--modes", default="memory,stream", help="comma-separated: memory, stream")
    p.add_argument("-M", "--components", type=int, default=5, help="mixture components")
    p.add_argument("-q", "--latent", type=int, default=60, help="latent dimension per component")
    p.add_argument("--max-iter", type=int, default=2, help="EM iterations (memory does not depend on it)")
    p.add_argument("--json", type=Path, default=None, help="also write the rows to this JSON file")
    a = p.parse_args(argv)
    rows = run_memory_bench(a.data, tuple(int(k) for k in a.repeat.split(",")),
                            tuple(m.strip() for m in a.modes.split(",") if m.strip()), a.components, a.latent,
                            a.max_iter)
    print(to_markdown(rows))
    if a.json is not None:
        tmp = a.json.with_name(f".{a.json.name}.tmp")
        tmp.write_text(json.dumps(rows, indent=2))
        tmp.replace(a.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
