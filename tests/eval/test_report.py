"""Report aggregation against direct numpy computations on hand-built rows."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from silpose.eval.report import e1_comparison, headline, markdown_summary, stats


def _rows(rng, n=30):
    parts = []
    for k in range(4):
        d = {"experiment": "E1", "method": "mppca", "training": "single-view", "trained_views": str(k),
             "input_views": str(k), "n_input_views": 1, "noise": "standard", "sample_id": np.arange(n),
             "pose_cm": rng.gamma(4, 5, n), "pose_pa_cm": rng.gamma(4, 3, n)}
        for v in range(4):
            d[f"chamfer_v{v}"] = rng.gamma(3, 1, n) if v == k else np.full(n, np.nan)
        parts.append(pd.DataFrame(d))
    d = {"experiment": "E1", "method": "mppca", "training": "multi-view", "trained_views": "0123", "input_views": "0123",
         "n_input_views": 4, "noise": "standard", "sample_id": np.arange(n), "pose_cm": rng.gamma(4, 3, n),
         "pose_pa_cm": rng.gamma(4, 2, n)}
    for v in range(4):
        d[f"chamfer_v{v}"] = rng.gamma(3, 0.8, n)
    parts.append(pd.DataFrame(d))
    for views in ("0123", "0", "1"):
        parts.append(pd.DataFrame({"experiment": "E2", "method": "mppca", "training": "multi-view",
                                   "trained_views": "0123", "input_views": views, "n_input_views": len(views),
                                   "noise": "standard", "sample_id": np.arange(n), "pose_cm": rng.gamma(4, 2, n),
                                   "pose_pa_cm": rng.gamma(4, 1, n), "chamfer_px": rng.gamma(3, 1, n),
                                   "chamfer_sym_px": rng.gamma(3, 1, n), "chamfer_observed_px": rng.gamma(3, 1, n),
                                   "chamfer_missing_px": rng.gamma(3, 1, n)}))
        for kind in ("knn", "ridge"):
            parts.append(pd.DataFrame({"experiment": "E4", "method": kind, "training": "multi-view",
                                       "trained_views": views, "input_views": views, "n_input_views": len(views),
                                       "noise": "standard", "sample_id": np.arange(n), "pose_cm": rng.gamma(4, 2.2, n),
                                       "pose_pa_cm": rng.gamma(4, 1, n)}))
    parts.append(pd.DataFrame({"experiment": "E4", "method": "chance", "training": "-", "trained_views": "-",
                               "input_views": "-", "n_input_views": 0, "noise": "-", "sample_id": np.arange(n),
                               "pose_cm": rng.gamma(6, 5, n), "pose_pa_cm": rng.gamma(6, 3, n)}))
    return pd.concat(parts, ignore_index=True)


def test_stats_matches_numpy():
    v = np.random.default_rng(0).normal(size=101)
    s = stats(np.r_[v, np.nan])
    assert s["n"] == 101 and s["mean"] == pytest.approx(v.mean())
    assert [s["q1"], s["median"], s["q3"]] == pytest.approx(np.percentile(v, [25, 50, 75]).tolist())


def test_e1_improvements_are_computed_from_matching_rows():
    df = _rows(np.random.default_rng(1))
    c = e1_comparison(df)
    e1 = df[df.experiment == "E1"]
    sv, mv = e1[e1.training == "single-view"], e1[e1.training == "multi-view"]
    assert c["pose_improvement_pct"] == pytest.approx(100 * (1 - mv.pose_cm.mean() / sv.pose_cm.mean()))
    sv_c = np.mean(np.concatenate([sv[sv.trained_views == str(k)][f"chamfer_v{k}"] for k in range(4)]))
    mv_c = np.mean(np.concatenate([mv[f"chamfer_v{k}"] for k in range(4)]))
    assert c["contour_improvement_pct"] == pytest.approx(100 * (1 - mv_c / sv_c))


def test_headline_and_markdown():
    df = _rows(np.random.default_rng(2))
    h = headline(df)
    e2 = df[df.experiment == "E2"]
    assert h["pose_cm_by_n_views"][1]["mean"] == pytest.approx(e2[e2.n_input_views == 1].pose_cm.mean())
    for r in h["mppca_vs_baselines_by_subset"]:
        m = e2[e2.input_views == r["views"]].pose_cm.mean()
        knn = df[(df.experiment == "E4") & (df.method == "knn") & (df.input_views == r["views"])].pose_cm.mean()
        assert r["mppca"] == pytest.approx(m) and r["knn"] == pytest.approx(knn)
        assert r["mppca_best"] == (m < min(r["knn"], r["ridge"]))
    md = markdown_summary(df, {"seed": 0}, "t")
    assert "## E1" in md and "## E2" in md and "## E4" in md and '"seed": 0' in md


def _cells(values) -> str:
    v = np.asarray(values, np.float64)
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return f"{v.mean():.2f} | {med:.2f} | {q1:.2f} | {q3:.2f}"


def test_markdown_rows_hold_the_statistics_of_their_rows():
    """Table rows of summary.md, recomputed from the hand-built rows with numpy (not with report.stats)."""
    df = _rows(np.random.default_rng(4))
    lines = markdown_summary(df, {"test_contour_length_px_mean": 400.0, "test_area_px_mean": 2000.0}, "t").splitlines()
    e2, e4 = df[df.experiment == "E2"], df[df.experiment == "E4"]
    one = e2[e2.n_input_views == 1]
    pct = 100.0 * 400.0 / 2000.0 * one.chamfer_px.mean()  # the paper's normalisation: Chamfer x length / area
    want = (f"| 1 | {len(one)} | {_cells(one.pose_cm)} | 15 | {_cells(one.chamfer_px)} | {pct:.1f} | "
            f"{one.chamfer_observed_px.mean():.2f} | {one.chamfer_missing_px.mean():.2f} | {one.chamfer_sym_px.mean():.2f} | "
            f"{one.pose_pa_cm.mean():.2f} |")
    assert want in lines
    chance = e4[e4.method == "chance"].pose_cm
    assert f"| chance (random training pose) | – | {_cells(chance)} | 29 |" in lines
    ridge = e4[(e4.method == "ridge") & (e4.n_input_views == 1)].pose_cm
    assert f"| ridge regression | 1 | {_cells(ridge)} |  |" in lines


def _robust_rows(rng, views, n=30, noise="standard"):
    return [pd.DataFrame({"experiment": "E3", "method": "mppca robust", "training": "multi-view", "trained_views": "0123",
                          "input_views": v, "n_input_views": len(v), "noise": noise, "sample_id": np.arange(n),
                          "pose_cm": rng.gamma(4, 2, n), "pose_pa_cm": rng.gamma(4, 1, n)}) for v in views]


def test_robust_figures_beside_the_baselines_need_every_view_alone():
    """The headline's robust one-view figure is the mean over every view alone (as kNN's is over its one-view
    subsets), with E2's noise only; with view 0 alone scored (as for the mask noise) there is none."""
    rng = np.random.default_rng(5)
    base = _rows(rng)
    partial = pd.concat([base, *_robust_rows(rng, ("0123", "0"))], ignore_index=True)
    by = headline(partial)["pose_mean_cm_by_method_and_n_views"]
    assert "mppca robust" not in by[1]
    assert by[4]["mppca robust"] == pytest.approx(partial[(partial.method == "mppca robust") & (partial.input_views == "0123")]
                                                  .pose_cm.mean())
    rows = _robust_rows(rng, ("0123", "0", "1", "2", "3")) + _robust_rows(rng, ("1", "2", "3"), noise="mask mild")
    full = pd.concat([base, *rows], ignore_index=True)
    alone = full[(full.method == "mppca robust") & (full.n_input_views == 1) & (full.noise == "standard")]
    want = np.mean([alone[alone.input_views == v].pose_cm.mean() for v in "0123"])  # 30 rows each: the plain mean
    assert headline(full)["pose_mean_cm_by_method_and_n_views"][1]["mppca robust"] == pytest.approx(want)
