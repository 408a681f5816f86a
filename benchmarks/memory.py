"""Peak memory (RSS) of the in-memory vs the streaming (out-of-core) MPPCA fit.

Section ``memory`` of ``python -m benchmarks.run``; for another dataset or sizes, e.g.
``python -m benchmarks.run --only memory --set memory.data=data/paper --set memory.repeats=[1,2,4]``.

Each measurement runs in its own Python subprocess: it imports everything, records its RSS
(``baseline``), fits the shape+structure model on the dataset's train split, and reports the
process's peak RSS (``getrusage`` ``ru_maxrss``, exact, not sampled). ``fit`` = peak - baseline.

``repeats`` k makes the dataset k times larger *for this measurement only*: the in-memory fit
concatenates k copies of the split's arrays, the streaming fit reads the same shard files k times
per pass (a k-fold longer list of shards, same shard size). The trainer itself has no such option.
Memory does not depend on the number of EM iterations (each is one pass over the same data), so
``max_iter`` 2 keeps the runs short; the hyperparameters default to M 5, q 60 (the model defaults
are M 60, q 40 where the data support it). Without the dataset, see :mod:`benchmarks.inputs` (``fallback``).
"""

from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path

from . import inputs, subproc


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

    from silpose.model import ShapeStructureModel
    from silpose.model.streaming import DatasetShards
    from silpose.shared.dataset import load_split

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


def run(data: str = "data/default", repeats=(1, 2, 4), modes=("memory", "stream"), n_components: int = 5,
        n_latent: int = 60, max_iter: int = 2, fallback: str = "skip") -> list[dict]:
    """One subprocess per (mode, repeat); rows as :func:`measure` returns them plus ``data`` (what was
    measured), and the ratio of each streaming fit's memory to the in-memory fit's at the same size
    (``fit_mb_vs_memory``) when both ran. A missing ``data`` folder: see :func:`benchmarks.inputs.resolve`.
    A failed measurement raises RuntimeError."""
    with tempfile.TemporaryDirectory(prefix="silpose-bench-memory-") as tmp:
        src = inputs.resolve("memory", data, None, fallback, Path(tmp))
        if src.skip:
            return [inputs.skip_row("memory", src.skip)]
        rows = []
        for repeat in repeats:
            for mode in modes:
                args = dict(mode=mode, data=str(src.data), repeat=int(repeat), n_components=n_components,
                            n_latent=n_latent, max_iter=max_iter)
                res = subproc.call(__name__, "measure", args)
                if res.error:
                    raise RuntimeError(f"memory: {mode} x{repeat} failed ({res.error})")
                rows.append({**res.value, "data": src.label})
    by_key = {(r["mode"], r["repeat"]): r for r in rows}
    for r in rows:
        ref = by_key.get(("memory", r["repeat"]))
        if r["mode"] == "stream" and ref is not None:
            r["fit_mb_vs_memory"] = r["fit_mb"] / ref["fit_mb"] if ref["fit_mb"] > 0 else float("nan")
    return rows
