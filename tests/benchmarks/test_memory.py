"""The memory benchmark repeats the dataset for the measurement only, one subprocess per fit."""

import math

from benchmarks.inputs import TINY_SPLITS
from benchmarks.memory import run


def test_memory_repeats_shards_for_the_measurement_only(tiny_dir):
    rows = run(str(tiny_dir / "data"), repeats=(2,), modes=("stream", "memory"), n_components=2, n_latent=3,
               max_iter=1)
    n = TINY_SPLITS["train"]
    assert [(r["mode"], r["repeat"], r["n_rows"]) for r in rows] == [("stream", 2, 2 * n), ("memory", 2, 2 * n)]
    assert all(r["peak_mb"] >= r["baseline_mb"] > 0 and r["shard_rows"] == 40 for r in rows)
    for r in rows:
        assert math.isclose(r["fit_mb"], r["peak_mb"] - r["baseline_mb"], rel_tol=1e-9, abs_tol=1e-9)
        if r["mode"] == "stream":
            ref = next(m for m in rows if m["mode"] == "memory" and m["repeat"] == r["repeat"])
            assert r["fit_mb_vs_memory"] == r["fit_mb"] / ref["fit_mb"]


def test_memory_without_data_skips_in_full_runs(tmp_path):
    rows = run(str(tmp_path / "absent"), fallback="skip")
    assert len(rows) == 1 and "absent" in rows[0]["skipped"]
