"""End to end: `silpose eval` on a tiny stick-figure dataset writes every artefact, with numbers
that can be recomputed independently from the model, the noise and the metrics."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from silpose.shared import metrics
from silpose.eval.baselines import ChanceBaseline
from silpose.eval.noise import STANDARD_NOISE, apply_noise
from silpose.model.persistence import load_model, save_model
from silpose.app.training import fit_dataset
from silpose.model.shape_model import ShapeStructureModel
from silpose.shared.cli import build_app
from silpose.shared.contours import normalise
from silpose.shared.dataset import load_split

ARTEFACTS = ("results.parquet", "headline.json", "summary.md", "e1_single_vs_multi.png", "e2_missing_views.png",
             "e3_noise.png", "e4_baselines.png", "e5_single_view.png", "e5_missing_view.png", "e6_robust_mask.png",
             "e6_garbage.png")


@pytest.fixture(scope="module")
def evaluated(stick_dataset, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("eval")
    train = load_split(stick_dataset, "train")
    model = fit_dataset(ShapeStructureModel(n_components=2, n_latent=4, n_init=1, max_iter=30, tol=1e-3,
                                            random_state=0), train)
    model.calibrate_plausibility(train.contours[:20])  # as silpose train does with its held-out part
    save_model(tmp / "m.npz", model)
    out = tmp / "report"
    res = CliRunner().invoke(build_app(), ["eval", str(stick_dataset), "--model", str(tmp / "m.npz"),
                                           "--out", str(out), "--quick-sweep"])
    assert res.exit_code == 0, res.output + repr(res.exception)
    return stick_dataset, tmp / "m.npz", out


def test_every_artefact_is_written(evaluated):
    _, _, out = evaluated
    for name in ARTEFACTS:
        assert (out / name).is_file(), name
    for name in ARTEFACTS:
        if name.endswith(".png"):
            img = cv2.imread(str(out / name))
            assert img is not None and img.shape[0] > 200 and img.std() > 10, name  # a real, non-blank image
    assert not list(out.glob(".*tmp"))  # no temporaries left behind
    cover = json.loads((out / "coverage.json").read_text())  # the walk-only stick figures have no groups
    assert "groups" not in cover and cover["n_test"] == cover["model"]["n"] > 0
    assert not (out / "sequences.json").exists()  # E7 needs a dataset written by silpose gen
    assert cover["model"]["in_sample_mean_cm"] > 0
    head = json.loads((out / "headline.json").read_text())  # the test figure is E4's robust answer, every view
    robust = head["pose_mean_cm_by_method_and_n_views"]["4"]["mppca robust"]
    assert cover["model"]["test_mean_cm"] == pytest.approx(robust, rel=1e-9)


def _quartet(values) -> str:
    """'mean | median | Q1 | Q3' cells, recomputed here with numpy from the raw per-example values."""
    v = np.asarray(values, np.float64)
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return f"{v.mean():.2f} | {med:.2f} | {q1:.2f} | {q3:.2f}"


def test_summary_and_headline_show_figures_recomputed_from_the_rows(evaluated):
    """summary.md and headline.json carry the statistics of results.parquet's rows (recomputed here),
    next to the paper's figures."""
    _, _, out = evaluated
    df = pd.read_parquet(out / "results.parquet")
    lines = (out / "summary.md").read_text().splitlines()
    head = json.loads((out / "headline.json").read_text())
    e2 = df[df.experiment == "E2"]
    for n, paper in ((4, "3"), (1, "15"), (2, "–")):
        pose = e2[e2.n_input_views == n].pose_cm.to_numpy()
        row = f"| {n} | {len(pose)} | {_quartet(pose)} | {paper} | {_quartet(e2[e2.n_input_views == n].chamfer_px)} |"
        assert any(line.startswith(row) for line in lines), row
        assert head["pose_cm_by_n_views"][str(n)]["mean"] == pytest.approx(pose.mean(), rel=1e-12)
        assert head["pose_cm_by_n_views"][str(n)]["n"] == len(pose)
    e1 = df[df.experiment == "E1"]
    single, multi = e1[e1.training == "single-view"].pose_cm.mean(), e1[e1.training == "multi-view"].pose_cm.mean()
    better = 100.0 * (1.0 - multi / single)
    per_view = e1[e1.training == "single-view, equal q per view"].pose_cm.mean()
    better_pv = 100.0 * (1.0 - multi / per_view)
    assert f"| pose (mean) | {better:.1f} % | {better_pv:.1f} % | 24 % |" in lines
    assert head["e1"]["pose_improvement_pct"] == pytest.approx(better, rel=1e-12)
    assert head["e1_equal_q_per_view"]["pose_improvement_pct"] == pytest.approx(better_pv, rel=1e-12)
    # the headline table: mask-level noise with every view given, as a multiple of the clean error
    for method, ratio in (("mppca", "x_clean"), ("mppca robust", "x_clean_robust")):
        e3 = df[(df.experiment == "E3") & (df.method == method) & (df.input_views == "0123")]
        clean = e3[e3.noise == "clean"].pose_cm.mean()
        assert set(e3.noise) == {k for k, v in head["pose_mean_cm_by_noise_all_views"].items() if method in v}
        for noise, g in e3.groupby("noise"):
            v = head["pose_mean_cm_by_noise_all_views"][noise]
            assert v[method] == pytest.approx(g.pose_cm.mean(), rel=1e-12)
            assert v[ratio] == pytest.approx(v[method] / clean, rel=1e-12)
    mask = [k for k in head["pose_mean_cm_by_noise_all_views"] if k.startswith("mask")]
    assert mask and all(any(line.startswith(f"| 4 views, noise '{k}' |") for line in lines) for k in mask)
    assert lines.index("## Headline") < lines.index(next(x for x in lines if x.startswith("## E1")))
    chance = df[(df.experiment == "E4") & (df.method == "chance")].pose_cm
    assert f"| chance (random training pose) | – | {_quartet(chance)} | 29 |" in lines
    assert head["chance_cm"]["mean"] == pytest.approx(chance.mean(), rel=1e-12)
    knn4 = df[(df.experiment == "E4") & (df.method == "knn") & (df.n_input_views == 4)].pose_cm
    assert f"| kNN regression | 4 | {_quartet(knn4)} |  |" in lines


def test_row_counts_match_the_protocol(evaluated):
    root, _, out = evaluated
    df = pd.read_parquet(out / "results.parquet")
    n = len(load_split(root, "test"))
    counts = df.groupby("experiment").size().to_dict()
    assert counts["E1"] == 2 * 4 * n + n  # single-view models at equal q and at q / K, and the 4-view model
    assert counts["E2"] == 15 * n
    # quick sweep: 4 settings x (2 MPPCA inputs + kNN + ridge + MLP), plus E6's robust MPPCA rows for the settings
    # of silpose.eval.e6_inference.ROBUST_SPECS in the sweep (clean, mask strong: all views and view 0) and the
    # standard noise (all views and each of the 4 views alone)
    assert counts["E3"] == 4 * (2 + 3) * n + 2 * 2 * n + 5 * n
    robust = df[(df.experiment == "E3") & (df.method == "mppca robust")]
    assert sorted(robust.noise.unique()) == ["clean", "mask strong", "standard"]
    alone = robust[robust.n_input_views == 1]
    assert alone.groupby("noise").input_views.nunique().to_dict() == {"clean": 1, "mask strong": 1, "standard": 4}
    assert counts["E4"] == n + 3 * 15 * n  # chance, kNN, ridge and MLP on every view subset
    e2 = df[df.experiment == "E2"]
    assert sorted(e2.groupby("n_input_views").input_views.nunique().to_dict().items()) == [(1, 4), (2, 6), (3, 4), (4, 1)]


def test_numbers_recompute_independently(evaluated):
    root, model_path, out = evaluated
    df = pd.read_parquet(out / "results.parquet")
    test, train = load_split(root, "test"), load_split(root, "train")
    model = load_model(model_path)
    noisy = apply_noise(STANDARD_NOISE, test.contours, test.sample_id, seed=0)
    present = np.zeros((len(test), 4), bool)
    present[:, [0, 2]] = True
    res = model.infer(noisy, views_present=present, centroid=test.centroid, scale=test.scale)
    rows = df[(df.experiment == "E2") & (df.input_views == "02")].set_index("sample_id").loc[test.sample_id]
    np.testing.assert_allclose(rows.pose_cm, metrics.pose_error_cm(res.joints, test.joints), rtol=1e-6)
    # missing view 1 is placed with its true normalisation; compare one Chamfer value from scratch
    recon_v1 = metrics.place_contours(res.contours_norm[:1, 1:2], test.centroid[:1, 1:2], test.scale[:1, 1:2])[0, 0]
    h, w = test.rig.cameras[1].height, test.rig.cameras[1].width
    assert rows.chamfer_v1.iloc[0] == pytest.approx(metrics.chamfer_one_sided(test.contours[0, 1], recon_v1, h, w), rel=1e-3)
    chance = df[(df.experiment == "E4") & (df.method == "chance")].set_index("sample_id").loc[test.sample_id]
    pred = ChanceBaseline(random_state=0).fit(train.joints).predict(len(test))
    np.testing.assert_allclose(chance.pose_cm, metrics.pose_error_cm(pred, test.joints), rtol=1e-9)
    assert df[df.experiment == "E1"].pose_cm.notna().all()
    # E1 at equal capacity per view: single-view model k has q / K latent dimensions, refitted here
    e1 = df[(df.experiment == "E1") & (df.training == "single-view, equal q per view") & (df.trained_views == "2")]
    params = dict(model.get_params(), views=(2,), n_latent=max(1, round(model.n_latent / 4)))
    fitted_on = train  # the stick model was fitted on every training sample (no held-out part)
    sv = ShapeStructureModel(**params).fit(fitted_on.contours, fitted_on.joints, rig=fitted_on.rig)
    only2 = np.zeros((len(test), 4), bool)
    only2[:, 2] = True
    pred = sv.infer(noisy, views_present=only2, centroid=test.centroid, scale=test.scale).joints
    np.testing.assert_allclose(e1.set_index("sample_id").loc[test.sample_id].pose_cm,
                               metrics.pose_error_cm(pred, test.joints), rtol=1e-6)


def test_clear_errors_when_data_or_model_missing(tmp_path, stick_dataset):
    runner = CliRunner()
    res = runner.invoke(build_app(), ["eval", str(tmp_path / "nope")])
    assert res.exit_code == 2 and "silpose gen nope" in res.output
    res = runner.invoke(build_app(), ["eval", str(stick_dataset), "--model", str(tmp_path / "none.npz")])
    assert res.exit_code == 2 and "silpose train stick" in res.output


def test_e6_tables_recompute_independently(evaluated):
    root, model_path, out = evaluated
    e6 = json.loads((out / "headline.json").read_text())["e6"]
    assert "## E6" in (out / "summary.md").read_text()
    test = load_split(root, "test")
    model = load_model(model_path)
    noisy = apply_noise(STANDARD_NOISE, test.contours, test.sample_id, seed=0)
    res = model.infer(noisy, hypotheses=3, consensus=True)
    # heading recomputed by hand: forward = (a_y, -a_x) of the hip + shoulder axis a (left side minus right)
    def facing(j):
        a = (j[..., 11, :] - j[..., 15, :]) + (j[..., 5, :] - j[..., 8, :])
        return np.arctan2(-a[..., 0], a[..., 1])
    def angle(a, b):
        return np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)
    row = next(r for r in e6["flips"] if r["condition"] == "4 views, standard")
    diff = angle(facing(res.hypotheses.best_joints), facing(test.joints))
    assert row["consensus_flips_pct"] == pytest.approx(100 * np.mean(diff > np.pi / 2))
    # the single answer: the posterior mean, or the top-1 hypothesis where it faces the other way
    top1 = res.hypotheses.joints[:, 0]
    single = np.where((angle(facing(top1), facing(res.joints)) > np.pi / 2)[:, None, None], top1, res.joints)
    diff = angle(facing(single), facing(test.joints))
    assert row["single_answer_flips_pct"] == pytest.approx(100 * np.mean(diff > np.pi / 2))
    assert row["best_of_3_pose_cm"] <= row["single_answer_pose_cm"] + 1e-9  # the oracle cannot be worse
    untangled = [r for r in e6["self_intersection"] if r["untangled_pct"] is not None]
    assert untangled and all(r["untangled_pct"] == 0.0 for r in untangled)
    garbage = {g["kind"]: g for g in e6["plausibility"]["garbage"]}
    assert garbage["all-black"]["no_silhouette_pct"] == 100.0 and garbage["all-black"]["flagged_pct"] == 100.0
    assert garbage["all-white"]["flagged_pct"] == 100.0
    assert len(e6["missing_view"]) == 4 and all(r["nearest_neighbour_px"] > 0 for r in e6["missing_view"])
    # the robust missing-view column: view 0 inferred from views 1-3 by silpose infer's default inference
    row = e6["missing_view"][0]
    given = np.ones((len(test), 4), bool)
    given[:, 0] = False
    clean = np.asarray(test.contours, np.float64)
    _, centroid, scale = normalise(clean)
    rec = model.infer(noisy, views_present=given, centroid=centroid, scale=scale, robust=True).contours_px
    cam = test.rig.cameras[0]
    one, _ = metrics.chamfer_errors(clean[:, :1], rec[:, :1], (cam.height, cam.width))
    assert row["mppca_robust_px"] == pytest.approx(float(np.nanmean(one)), rel=1e-9)
    assert row["ratio_robust"] == pytest.approx(row["mppca_robust_px"] / row["nearest_neighbour_px"])
