"""The render benchmark on a few samples: it drives the generator's worker entry point in spawned
processes and its rows are consistent with their own timings."""

import math

from benchmarks.generation import run


def test_generation_rows_are_consistent_with_their_timings():
    rows = run(n_samples=3, renderers=("raster",), processes=1, memory_samples=2, shard_size=1)
    speed, memory = rows
    assert (speed["name"], speed["processes"], speed["samples"]) == ("raster x1", 1, 3)
    assert memory["name"] == "memory raster x1" and len(memory["rss_curve_mb"]) == 3  # after warm-up + 2 shards
    for r in rows:
        assert r["seconds"] > 0 and r["rss_start_mb"] > 0
        assert math.isclose(r["samples_per_s"], r["samples"] / r["seconds"], rel_tol=1e-12)
        assert math.isclose(r["ms_per_sample"], 1e3 * r["seconds"] * r["processes"] / r["samples"], rel_tol=1e-12)
        assert math.isclose(r["rss_growth_mb"], r["rss_end_mb"] - r["rss_start_mb"], rel_tol=1e-12)
    assert "raster_speedup" not in speed  # only other renderers are compared with the raster one
