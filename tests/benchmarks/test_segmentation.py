"""The segmentation benchmark on a tiny input: its rows are consistent (no timing assertions)."""

import math

from silpose.segment.bench import format_table, run_segment_bench


def test_bench_rows_are_consistent():
    rows = run_segment_bench(n_frames=6, size=(160, 120), n_background=8)
    by = {r["method"].strip(): r for r in rows}
    stream, batch = by["BackgroundModel.segment (streaming)"], by["BackgroundModel.segment_batch"]
    assert stream["iou"] == batch["iou"]  # the same masks through both APIs
    assert by["no shadow rejection (ncc_threshold=None)"]["iou"] < stream["iou"]
    assert rows[0]["ratio_to_mog2"] == 1.0
    for r in rows:
        assert r["frames_per_s"] > 0 and r["cpu_frames_per_s"] > 0 and math.isclose(
            r["ms_per_frame"], 1e3 / r["frames_per_s"], rel_tol=1e-9
        )
    assert format_table(rows).count("\n") == len(rows) + 1
