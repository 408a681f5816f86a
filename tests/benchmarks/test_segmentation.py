"""The segmentation benchmark on a tiny input: its rows are consistent with their own timings."""

import math

from benchmarks.segmentation import run


def test_segmentation_rows_are_consistent_with_their_timings():
    rows = run(n_frames=6, size=(160, 120), n_background=8, hd_frames=0, rendered=False)
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
    for name in ("BackgroundModel.segment (streaming)", "no shadow rejection (ncc_threshold=None)"):
        r = by[name]  # the same-resolution comparison with the MOG2 row
        assert r["same_size_mog2"] == mog["method"]
        assert math.isclose(r["time_vs_same_size_mog2"], (r["cpu_s"] / r["frames"]) / (mog["cpu_s"] / mog["frames"]))
        assert math.isclose(r["iou_minus_same_size_mog2"], r["iou"] - mog["iou"])


def test_best_of_keeps_the_fastest_pass_per_frame(monkeypatch):
    """Repeated passes: the masks of the last pass, and per frame the smallest of the passes' times."""
    import numpy as np

    from benchmarks import segmentation

    passes = iter([(np.zeros((2, 3, 4), bool), np.array([3.0, 1.0]), np.array([2.0, 1.0])),
                   (np.ones((2, 3, 4), bool), np.array([2.0, 5.0]), np.array([4.0, 0.5]))])
    monkeypatch.setattr(segmentation, "_stream", lambda fn, frames: next(passes))
    masks, sec, cpu = segmentation._best_of({"a": None}, np.zeros((2, 3, 4)), repeats=2)["a"]
    assert masks.all()
    np.testing.assert_array_equal(sec, [2.0, 1.0])
    np.testing.assert_array_equal(cpu, [2.0, 0.5])


def test_rendered_rows_score_each_camera_against_its_truth(tmp_path):
    """run_rendered on a frames dataset (composited from a tiny dataset's true masks, the frames-dataset layout):
    its BackgroundModel row equals segmenting each camera's PNGs by hand, with a model learnt on that camera's
    empty-room PNGs, scored against the test split's masks; no dataset gives one row saying so."""
    import cv2
    import numpy as np

    from benchmarks.frames_composite import write_composite_frames
    from benchmarks.segmentation import run_rendered
    from silpose.datagen.testing import synthetic_record
    from silpose.segment import BackgroundModel
    from silpose.shared.camera import default_rig
    from silpose.shared.dataset import load_split, write_shard
    from silpose.shared.dataset_schema import build_metadata
    from silpose.shared.metrics import mask_iou

    root = tmp_path / "tiny"
    root.mkdir()
    rig = default_rig()
    config = {"name": "tiny", "seed": 3, "rig": rig.to_dict(), "n_points": 24}
    meta = build_metadata(rig.to_dict()["cameras"], config, 24, generator_version="test")
    write_shard(root / "test-00000-of-00001.parquet", [synthetic_record(config, "test", i) for i in range(3)], meta)
    frames = write_composite_frames(root, root / "frames", n_background=6, seed=1)

    rows = run_rendered(str(frames), repeats=1)
    mog, ours = rows
    assert "MOG2" in mog["method"] and "BackgroundModel" in ours["method"]
    truth = load_split(frames, "test", with_masks=True)
    ious = []
    for k, cam in enumerate(truth.rig.names):
        read = lambda folder: np.stack([cv2.imread(str(p), cv2.IMREAD_COLOR) for p in sorted(folder.glob("*.png"))])  # noqa: E731
        model = BackgroundModel().fit(read(frames / "background" / cam))
        views = read(frames / "frames" / cam)
        ious += list(mask_iou(np.stack([model.segment(v) for v in views]), truth.masks[:, k] > 0))
    assert ours["frames"] == mog["frames"] == len(ious) == 3 * len(truth.rig.names)
    assert math.isclose(ours["iou"], float(np.mean(ious)), rel_tol=1e-12)
    assert ours["same_size_mog2"] == mog["method"]
    assert math.isclose(ours["iou_minus_same_size_mog2"], ours["iou"] - mog["iou"])
    assert math.isclose(ours["time_vs_same_size_mog2"], ours["cpu_s"] / mog["cpu_s"])  # same frame count
    assert "skipped" in run_rendered(str(tmp_path / "none"))[0]
