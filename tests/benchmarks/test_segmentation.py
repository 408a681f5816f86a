"""The segmentation benchmark on a tiny input: its rows are consistent with their own timings."""

import math

from benchmarks.segmentation import run


def test_segmentation_rows_are_consistent_with_their_timings():
    rows = run(n_frames=6, size=(160, 120), n_background=8, hd_frames=0)
    by = {r["method"].strip(): r for r in rows}
    mog = rows[0]
    assert mog["method"].startswith("cv2 MOG2")  # the reference every ratio divides by
    stream, batch = by["BackgroundModel.segment (streaming)"], by["BackgroundModel.segment_batch"]
    assert stream["iou"] == batch["iou"]  # the same masks through both APIs
    assert by["no shadow rejection (ncc_threshold=None)"]["iou"] < stream["iou"]
    mog_rate = mog["frames"] / mog["cpu_s"]
    for r in rows:
        assert r["seconds"] > 0 and r["cpu_s"] > 0
        # every derived figure recomputed from the row's own frame count and timings
        assert math.isclose(r["frames_per_s"], r["frames"] / r["seconds"], rel_tol=1e-12)
        assert math.isclose(r["cpu_frames_per_s"], r["frames"] / r["cpu_s"], rel_tol=1e-12)
        assert math.isclose(r["ms_per_frame"], 1e3 * r["seconds"] / r["frames"], rel_tol=1e-12)
        assert math.isclose(r["ratio_to_mog2"], (r["frames"] / r["cpu_s"]) / mog_rate, rel_tol=1e-12)
    streaming = [r for r in rows if not math.isnan(r["ms_p50"])]
    assert len(streaming) == 4 and all(r["ms_p50"] <= r["ms_p95"] for r in streaming)
