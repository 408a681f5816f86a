"""The README reads in five minutes: at most 230 lines, no line over 200 characters outside tables, no issue
numbers or dates; its generated tables match their sources; docs/results.py tolerates missing reports."""

from __future__ import annotations

import importlib.util
import json
import re
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _results_module():
    spec = importlib.util.spec_from_file_location("docs_results", ROOT / "docs" / "results.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_readme_is_short_and_undated():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 230
    long = [i + 1 for i, line in enumerate(lines) if len(line) > 200 and not line.startswith("|")]
    assert not long, f"lines over 200 characters: {long}"
    text = "\n".join(lines)
    assert not re.search(r"\bissues? #?\d+", text, re.I)
    assert not re.search(r"\b20\d\d-\d\d-\d\d\b", text)


def test_readme_links_exist():
    text = README.read_text(encoding="utf-8")
    for target in re.findall(r"\]\(([^)#]+)\)", text):
        if not target.startswith("http"):
            assert (ROOT / target).exists(), target


def test_results_generator_tolerates_missing_reports(tmp_path):
    mod = _results_module()
    readme = tmp_path / "README.md"
    shutil.copy(README, readme)
    out = tmp_path / "results.md"
    mod.main(["--reports", str(tmp_path / "no-reports"), "--out", str(out), "--readme", str(readme)])
    text = out.read_text()
    assert "not measured" in text and "Not measured: run `just bench`" in text
    block = readme.read_text().split("<!-- results:start -->")[1].split("<!-- results:end -->")[0]
    assert block.count("not measured") == 2 * len(mod.README_ROWS)  # default and paper columns


def test_results_come_from_the_report(tmp_path):
    mod = _results_module()
    reports = tmp_path / "reports"
    (reports / "default").mkdir(parents=True)
    head = {"paper": {"pose_4_views_cm": 3.0, "pose_1_view_cm": 15.0, "chance_cm": 29.0,
                      "multi_view_pose_improvement_pct": 24.0, "multi_view_contour_improvement_pct": 16.0},
            "pose_cm_by_n_views": {str(k): {"mean": float(k) + 0.123} for k in (1, 2, 3, 4)},
            "chance_cm": {"mean": 27.94}}
    (reports / "default" / "headline.json").write_text(json.dumps(head))
    readme = tmp_path / "README.md"
    shutil.copy(README, readme)
    mod.main(["--reports", str(reports), "--out", str(tmp_path / "r.md"), "--readme", str(readme)])
    block = readme.read_text().split("<!-- results:start -->")[1].split("<!-- results:end -->")[0]
    assert "| 4.12 / 3.12 / 2.12 / 1.12 | not measured | 3 / – / – / 15 |" in block
    assert "| 27.9 | not measured | 29 |" in block


def test_learning_curve_block_comes_from_the_motions_report(tmp_path):
    mod = _results_module()
    reports = tmp_path / "reports"
    (reports / "motions").mkdir(parents=True)
    rows = [{"n_samples": n, "n_components": m, "n_latent": 30, "pose_all_views_cm": n / 1000 + m / 100,
             "pose_1_view_cm": 2 * (n / 1000 + m / 100), "fit_s": 1.0, "n_test": 7}
            for n in (4000, 16000) for m in (15, 60) if (n, m) != (16000, 15)]
    (reports / "motions" / "learning_curve.json").write_text(json.dumps({"settings": {}, "rows": rows}))
    readme = tmp_path / "README.md"
    shutil.copy(README, readme)
    mod.main(["--reports", str(reports), "--out", str(tmp_path / "r.md"), "--readme", str(readme)])
    block = readme.read_text().split("<!-- curve:start -->")[1].split("<!-- curve:end -->")[0]
    assert "| 15 | 60 |" in block
    assert "| 4,000 | 4.15 / 8.30 | 4.60 / 9.20 |" in block
    assert "| 16,000 | – | 16.60 / 33.20 |" in block  # a point not measured
    assert "N 16,000 M 60: 1 s" in (tmp_path / "r.md").read_text()
    mod.main(["--reports", str(tmp_path / "none"), "--out", str(tmp_path / "r.md"), "--readme", str(readme)])
    assert "not measured" in readme.read_text().split("<!-- curve:start -->")[1].split("<!-- curve:end -->")[0]


def test_coverage_section_comes_from_each_presets_coverage_report(tmp_path):
    mod = _results_module()
    reports = tmp_path / "reports"
    (reports / "motions").mkdir(parents=True)
    cov = {"mean_cm": 10.584, "median_cm": 9.35, "n_train": 48000, "n_test": 400,
           "groups": {"walk": {"mean_cm": 7.591, "n": 16}, "bend": {"mean_cm": 13.716, "n": 107}},
           "model": {"n": 400, "noise": "standard", "inference": "robust, every view", "in_sample_mean_cm": 12.004,
                     "in_sample_median_cm": 9.111, "test_mean_cm": 16.488, "test_median_cm": 11.5}}
    (reports / "motions" / "coverage.json").write_text(json.dumps(cov))
    readme = tmp_path / "README.md"
    shutil.copy(README, readme)
    mod.main(["--reports", str(reports), "--out", str(tmp_path / "r.md"), "--readme", str(readme)])
    text = (tmp_path / "r.md").read_text()
    assert "nearest of 48,000 training poses to each of 400 test poses is 10.58 cm off" in text
    assert "| group | walk | bend |" in text and "| nearest training pose, cm | 7.59 | 13.72 |" in text
    assert ("The model (robust, every view, standard noise) on 400 of the samples it was fitted on: 12.00 cm "
            "(median 9.11); on the test poses: 16.49 cm (median 11.50)") in text


def test_speed_block_comes_from_the_bench_report(tmp_path):
    mod = _results_module()
    bench = tmp_path / "reports" / "bench"
    bench.mkdir(parents=True)
    rows_rec = [{"name": "run", "run": "3x", "steps": 90, "steps_per_s": 101.26, "steady_steps_per_s": 140.2},
                {"name": "run", "run": "colour 4 x 1932x1458", "steps": 30, "steps_per_s": 9.04,
                 "steady_steps_per_s": 22.0, "setup_s": 1.83},
                {"name": "accuracy", "input": "recording (lossy mask videos)", "joints_inside": 0.9987},
                {"name": "accuracy", "input": "recording, without the silhouette fit", "joints_inside": 0.9291}]
    rows_seg = [{"method": "ref", "iou": 0.99},
                {"method": "BackgroundModel.segment (streaming)", "iou": 0.9, "same_size_mog2": "ref",
                 "time_vs_same_size_mog2": 1.234},
                {"method": "rendered frames 320x240 (data/smoke/frames): cv2 MOG2", "iou": 0.88},
                {"method": "rendered frames 320x240 (data/smoke/frames): BackgroundModel.segment", "iou": 0.92,
                 "same_size_mog2": "rendered frames 320x240 (data/smoke/frames): cv2 MOG2",
                 "time_vs_same_size_mog2": 1.36}]
    rows_inf = [{"case": "batched, 4 views (joints + 4 contours)", "over_floor": 3.21, "value": 1000.0},
                {"case": "batched, 4 views, robust (8 reweighting passes)", "over_floor": 41.0, "value": 99.0}]
    data = {"quick": True, "machine": {"cpu_count": 2, "load_average": [0.5]},
            "sections": [{"section": "recordings", "rows": rows_rec}, {"section": "segmentation", "rows": rows_seg},
                         {"section": "inference", "rows": rows_inf},
                         {"section": "identities", "rows": [
                             {"name": "identities", "input": "mask videos", "tracker": "appearance", "ids": 5,
                              "identity_switches": 11, "frames": 200},
                             {"name": "identities", "input": "mask videos, walkers apart", "tracker": "appearance",
                              "ids": 4, "identity_switches": 4, "frames": 200, "joints_inside": 0.9941}]}]}
    (bench / "bench.json").write_text(json.dumps(data))
    readme = tmp_path / "README.md"
    shutil.copy(README, readme)
    mod.main(["--reports", str(tmp_path / "reports"), "--out", str(tmp_path / "r.md"), "--readme", str(readme)])
    block = readme.read_text().split("<!-- speed:start -->")[1].split("<!-- speed:end -->")[0]
    assert "| 101.3 time steps/s over 90 steps (140 after the set-up) |" in block
    assert "| 4 colour videos, 1932×1458 → joints, no overlays | 9.0 time steps/s over 30 steps" in block
    assert "| 1.23× MOG2's CPU time, IoU 0.900 vs 0.990 |" in block
    assert "| 3.2× / 41.0× (1,000 / 99 frames/s) |" in block
    assert "| segmentation, 320×240, frames rendered by Blender (textured room, shadows), vs MOG2 | 1.36× MOG2's " \
           "CPU time, IoU 0.920 vs 0.880 |" in block
    assert "| 2 walkers (mask videos): joints inside their own silhouette in the views used, fitted / not | " \
           "0.999 / 0.929 |" in block
    assert "walking apart (joints inside their own silhouette) | 5 / 11 over 200 steps; 4 / 4 (0.994) |" in block
    assert block.count("not measured") == 4  # overlays, two full-HD segmentation rows, single frame
    assert "### Summary" in (tmp_path / "r.md").read_text()
    assert "`just bench --quick`:" in block  # the quick defaults: no arguments named


def test_speed_block_names_the_arguments_a_bench_was_run_with(tmp_path):
    """A bench run with ``--set`` (here a longer recording, several runs of which the longest plain one counts)
    says so in the speed table's header and in docs/results.md."""
    mod = _results_module()
    rows_rec = [{"name": "run", "run": "1x", "steps": 150, "steps_per_s": 90.0, "steady_steps_per_s": 100.0},
                {"name": "run", "run": "3x", "steps": 450, "steps_per_s": 110.04, "steady_steps_per_s": 120.0},
                {"name": "run", "run": "3x, --robust", "steps": 450, "steps_per_s": 50.0, "steady_steps_per_s": 52.0}]
    data = {"quick": True, "machine": {"cpu_count": 2, "load_average": [0.5]},
            "sections": [{"section": "recordings", "kwargs": {"n_frames": 300, "repeat": 3, "train": 400,
                                                              "n_points": 200, "colour_frames": 150},
                          "rows": rows_rec}]}
    bench = tmp_path / "bench.json"
    bench.write_text(json.dumps(data))
    table = mod.speed_table(bench)
    assert table.splitlines()[0].startswith("| `just bench --quick` (recordings: n_frames 300): 2 cores")
    assert "| 110.0 time steps/s over 450 steps (120 after the set-up) |" in table


def test_bench_sections_measured_at_different_commits_each_name_theirs(tmp_path):
    """After ``just bench --update``, docs/results.md says which commit and date each section was measured at."""
    mod = _results_module()
    data = {"quick": False, "machine": {"cpu_count": 2, "commit": "bbb2222"},
            "sections": [{"section": "em", "what": "EM", "rows": [{"a": 1}], "commit": "aaa1111",
                          "date": "2026-01-01 10:00:00 UTC"},
                         {"section": "segmentation", "what": "seg", "rows": [{"a": 2}], "commit": "bbb2222",
                          "date": "2026-01-02 10:00:00 UTC"}]}
    bench = tmp_path / "bench.json"
    bench.write_text(json.dumps(data))
    text = "\n".join(mod.bench_section(bench))
    assert "EM. Measured at commit aaa1111, 2026-01-01 10:00:00 UTC." in text
    assert "seg. Measured at commit bbb2222, 2026-01-02 10:00:00 UTC." in text
    assert "each names its commit" in text
    data["sections"][0]["commit"] = "bbb2222"
    bench.write_text(json.dumps(data))
    assert "each names its commit" not in "\n".join(mod.bench_section(bench))


def test_the_speed_table_gives_the_overlay_share_of_each_mask_run_with_overlays():
    """Every mask run with overlays that has its share gets it, shortest first (the long run spreads the worker's
    start); without a colour run with overlays the row is not measured."""
    mod = _results_module()
    runs = [{"name": "run", "run": "10x with overlays", "steps": 1500, "overlay_share_wall": 0.25, "overlay_share_cpu": 0.45},
            {"name": "run", "run": "1x with overlays", "steps": 150, "overlay_share_wall": 0.31, "overlay_share_cpu": 0.5},
            {"name": "run", "run": "colour 4 x 9x9 with overlays", "steps": 60, "overlay_share_wall": 0.03,
             "overlay_share_cpu": 0.09}]
    label = "overlay videos' share of a run: wall time (CPU time), masks / colour"

    def share(rows):
        return dict(mod.speed_rows({"sections": [{"section": "recordings", "rows": rows}]}))[label]

    assert share(runs) == "31 % (50 %) over 150 steps and 25 % (45 %) over 1500 steps / 3 % (9 %) over 60 steps"
    assert share(runs[:2]) is None


def test_only_bench_rewrites_the_benchmark_tables_and_keeps_the_pose_tables(tmp_path):
    """``--only bench`` (a bench run on a machine without the pose reports): docs/results.md keeps everything before
    its Benchmarks heading byte for byte, and the README keeps every block but the speed table."""
    mod = _results_module()
    out, readme = tmp_path / "results.md", tmp_path / "README.md"
    shutil.copy(ROOT / "docs" / "results.md", out)
    shutil.copy(README, readme)
    before_md, before_readme = out.read_text(), readme.read_text()
    rows = [{"name": "run", "run": "10x", "steps": 1500, "steps_per_s": 171.25, "steady_steps_per_s": 180.0}]
    bench = tmp_path / "reports" / "bench" / "bench.json"
    bench.parent.mkdir(parents=True)
    bench.write_text(json.dumps({"quick": False, "machine": {"cpu_count": 2},
                                 "sections": [{"section": "recordings", "what": "recordings", "rows": rows}]}))
    mod.main(["--reports", str(tmp_path / "reports"), "--out", str(out), "--readme", str(readme), "--only", "bench"])
    head = before_md.split("\n## Benchmarks\n")[0]
    assert out.read_text().startswith(head + "\n## Benchmarks\n") and "171.2 time steps/s over 1500 steps" in out.read_text()
    speed = readme.read_text().split("<!-- speed:start -->")[1].split("<!-- speed:end -->")[0]
    assert "171.2 time steps/s over 1500 steps (180 after the set-up)" in speed
    for name in ("results", "formats", "curve"):
        block = f"<!-- {name}:start -->"
        assert readme.read_text().split(block)[1].split(f"<!-- {name}:end -->")[0] == \
            before_readme.split(block)[1].split(f"<!-- {name}:end -->")[0]
    with pytest.raises(SystemExit, match="not found: run `just bench` first"):
        mod.main(["--reports", str(tmp_path / "none"), "--out", str(out), "--readme", str(readme), "--only", "bench"])


def test_the_baselines_ahead_of_the_mppca_are_named(tmp_path):
    mod = _results_module()
    ahead = {"4": {"mppca": 3.9, "mppca robust": 3.3, "knn": 5.6, "ridge": 20.4, "mlp": 5.8},
             "2": {"mppca": 18.78, "knn": 17.69, "ridge": 27.0, "mlp": 18.5},
             "1": {"mppca": 10.8, "mppca robust": 10.22, "knn": 10.41, "ridge": 22.6, "mlp": 13.7}}
    assert mod._ahead({"pose_mean_cm_by_method_and_n_views": ahead}) == (
        "2 views: kNN 17.69, MLP 18.50 vs 18.78; 1 view: kNN 10.41 vs 10.80 (robust 10.22)")
    behind = {n: {**row, "knn": 99.0, "mlp": 99.0} for n, row in ahead.items()}
    assert mod._ahead({"pose_mean_cm_by_method_and_n_views": behind}) == "none (1–4 views)"
    assert mod._ahead({}) is None
    reports = tmp_path / "reports"
    (reports / "motions").mkdir(parents=True)
    (reports / "motions" / "headline.json").write_text(json.dumps({"pose_mean_cm_by_method_and_n_views": ahead}))
    readme = tmp_path / "README.md"
    shutil.copy(README, readme)
    mod.main(["--reports", str(reports), "--out", str(tmp_path / "r.md"), "--readme", str(readme)])
    assert "| 2 views: kNN 17.69, MLP 18.50 vs 18.78; 1 view: kNN 10.41 vs 10.80 (robust 10.22) |" in readme.read_text()
