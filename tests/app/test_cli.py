"""``silpose train`` / ``silpose infer`` (silpose.app) end to end on a tiny dataset written with the dataset writer.

The records come from ``silpose.datagen.testing.synthetic_record`` (stick-figure masks, real contour
extraction): fast, and written and read through ``silpose.shared.dataset`` like a generated dataset.
"""

import dataclasses
import json

import cv2
import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from silpose.datagen.testing import synthetic_record
from silpose.model.persistence import load_model, read_header
from silpose.model.augment import Roughness, augment_rows, roughen_contours, training_rows
from silpose.model.selection import DEFAULT_GRID, validation_split
from silpose.shared.camera import Rig, default_rig, ring_rig
from silpose.shared.cli import build_app
from silpose.shared.memory import peak_rss_bytes
from silpose.shared.dataset import load_split, write_shard
from silpose.shared.dataset_schema import build_metadata
from silpose.shared.rig_symmetry import rig_mirrors
from silpose.shared.skeleton import JOINT_NAMES
from silpose.model.hypotheses import TEMPORAL_HYPOTHESES, single_answer, temporal_choice

N_POINTS = 24


def write_dataset(root, name="tiny", **config_fields):
    """A dataset folder of 80 train and 6 test stick-figure samples (default rig); ``config_fields`` join its
    stored config (e.g. a preset's ``train`` table)."""
    root.mkdir()
    rig = default_rig()
    config = {"name": name, "seed": 3, "rig": rig.to_dict(), "n_points": N_POINTS, **config_fields}
    meta = build_metadata(rig.to_dict()["cameras"], config, N_POINTS, generator_version="test")
    for split, n in (("train", 80), ("test", 6)):
        records = [synthetic_record(config, split, i) for i in range(n)]
        write_shard(root / f"{split}-00000-of-00001.parquet", records, meta)
    (root / "manifest.json").write_text(json.dumps({"name": name}))
    return root


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return write_dataset(tmp_path_factory.mktemp("data") / "tiny")


@pytest.fixture(scope="module")
def trained(dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("models") / "tiny.npz"
    res = CliRunner().invoke(build_app(), ["train", str(dataset), "--out", str(out), "-M", "2", "-q", "4",
                                           "--n-init", "1", "--max-iter", "40", "--no-progress"])
    assert res.exit_code == 0, res.output
    return out, res.output


def _invoke(*args):
    return CliRunner().invoke(build_app(), [str(a) for a in args])


def test_train_writes_model_and_report(trained, dataset):
    out, output = trained
    assert "log-likelihood train" in output and "held-out" in output
    report = json.loads(out.with_suffix(".report.json").read_text())
    assert report["n_fit"] == 72 and report["n_heldout"] == 8
    assert report["em"]["n_iter"] == len(report["em"]["loglik_curve"]) >= 1
    # the process's peak memory (the CLI ran in this test process): Python with numpy holds more than 50 MB, and
    # the peak then can be no more than the process's peak now
    assert 0.05 < report["em"]["peak_rss_gib"] <= peak_rss_bytes() / 2**30
    assert f"peak memory of the process {report['em']['peak_rss_gib']:.2f} GiB" in out.with_suffix(".report.md").read_text()
    assert np.isfinite(report["heldout"]["mean_loglik"]) and report["heldout"]["joint_error_cm"] > 0
    # train vs held-out log-likelihood, both per sample for structure weight 1, recomputed from the model
    model = load_model(out)
    data = load_split(dataset, "train")
    fit_idx, held_idx = validation_split(80, 0.1, 0)
    w = model.structure_weight
    held = model.score_samples(data.contours[held_idx], data.joints[held_idx]).mean() + 57 * np.log(w)
    # the fitted rows: the clean samples, their mirrored people (the default rig has one mirror symmetry,
    # mirror "auto") and one ragged copy of each (roughness "auto" below 5,000 samples)
    mirrors = rig_mirrors(data.rig)
    assert report["mirrors"] == [m.to_dict() for m in mirrors] and len(mirrors) == 1
    assert report["roughness"] == Roughness().to_dict() and report["em"]["n_fit_rows"] == 2 * 2 * 72
    c_rows, j_rows = training_rows(data.contours[fit_idx], data.joints[fit_idx], fit_idx, rig=data.rig,
                                   mirrors=tuple(mirrors), roughness=Roughness(), seed=0)
    assert "mirrored person" in out.with_suffix(".report.md").read_text()
    train = model.score_samples(c_rows, j_rows).mean() + 57 * np.log(w)
    assert report["heldout"]["mean_loglik"] == pytest.approx(held, rel=1e-9)
    assert report["em"]["train_loglik"] == pytest.approx(train, rel=1e-6)
    assert report["em"]["real_em"] == (report["em"]["n_iter"] > 1 and report["em"]["em_gain"] > report["hyperparameters"]["tol"])
    md = out.with_suffix(".report.md").read_text()
    assert "EM moved from its k-means start" in md and f"held-out {report['heldout']['mean_loglik']:.1f}" in md
    assert "| iteration |" in md
    header = read_header(out)
    import hashlib
    assert header["dataset"]["manifest_sha256"] == hashlib.sha256((dataset / "manifest.json").read_bytes()).hexdigest()
    assert header["hyperparameters"]["n_components"] == 2 and header["rig"]["cameras"][0]["name"]


def test_infer_dataset_parquet_and_json_match_the_api(trained, dataset, tmp_path):
    model_path, _ = trained
    out = tmp_path / "j.parquet"
    res = _invoke("infer", model_path, dataset, "--out", out, "--contours")
    assert res.exit_code == 0, res.output
    table = pq.read_table(out).to_pandas()
    model = load_model(model_path)
    test = load_split(dataset, "test")
    # silpose infer: robust inference, top-3 hypotheses, the single answer, untangled contours
    ref = model.infer(test.contours, hypotheses=3, robust=True, untangle=True)
    got = np.stack([table[[f"{j}_x", f"{j}_y", f"{j}_z"]].to_numpy() for j in JOINT_NAMES], axis=1)
    np.testing.assert_array_equal(got, single_answer(ref.joints, ref.hypotheses).astype(np.float32))
    assert list(table["sample_id"]) == list(test.sample_id)
    assert list(table["hypothesis"]) == list(ref.hypotheses.chosen + 1)
    np.testing.assert_array_equal(table["hyp1_probability"], ref.hypotheses.probability[:, 0])
    # the model file carries its plausibility calibration; genuine frames are not flagged
    np.testing.assert_array_equal(table["plausibility"], ref.plausibility.astype(np.float32))
    assert list(table["status"]) == ["implausible" if f else "ok" for f in ref.implausible]
    with np.load(tmp_path / "j.contours.npz", allow_pickle=False) as z:
        np.testing.assert_array_equal(z["contours_norm"], ref.contours_norm)
        assert z["frames"].shape == (6,)
    res = _invoke("infer", model_path, dataset, "--out", tmp_path / "j.json", "--no-robust")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "j.json").read_text())
    plain = model.infer(test.contours, hypotheses=3)
    np.testing.assert_allclose(np.array([f["joints"] for f in doc["frames"]]), single_answer(plain.joints, plain.hypotheses), atol=1e-6)
    assert [len(f["hypotheses"]) for f in doc["frames"]] == list((plain.hypotheses.component >= 0).sum(axis=1))
    assert all(f["views_trimmed"] == [] and f["views_reindexed"] == [] for f in doc["frames"])  # --no-robust: none
    # --temporal: 8 hypotheses per frame, chosen along the frames by the Viterbi path; the answer is the chosen one
    res = _invoke("infer", model_path, dataset, "--out", tmp_path / "t.json", "--no-robust", "--temporal")
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "t.json").read_text())
    seq = model.infer(test.contours, hypotheses=TEMPORAL_HYPOTHESES)
    path = temporal_choice(seq.hypotheses)
    np.testing.assert_allclose(np.array([f["joints"] for f in doc["frames"]]),
                               seq.hypotheses.joints[np.arange(len(path)), path], atol=1e-6)
    assert [len(f["hypotheses"]) for f in doc["frames"]] == list((seq.hypotheses.component >= 0).sum(axis=1))
    # the views whose excursions robust inference trimmed, by camera name, in both formats
    names = model.rig_.names
    assert list(table["views_trimmed"]) == [",".join(names[k] for k in np.flatnonzero(r)) for r in ref.excursions_trimmed]
    assert list(table["views_reindexed"]) == [",".join(names[k] for k in np.flatnonzero(r)) for r in ref.reindexed]
    from silpose.app.writers import write_joints
    ref.excursions_trimmed = np.zeros_like(ref.views_present)
    ref.excursions_trimmed[1, [0, 2]] = True
    ref.reindexed = np.zeros_like(ref.views_present)
    ref.reindexed[2, 1] = True
    write_joints(tmp_path / "t.parquet", [f"f{i}" for i in range(6)], ref, names)
    write_joints(tmp_path / "t.json", [f"f{i}" for i in range(6)], ref, names)
    assert list(pq.read_table(tmp_path / "t.parquet")["views_trimmed"].to_pylist()) == ["", f"{names[0]},{names[2]}"] + [""] * 4
    assert json.loads((tmp_path / "t.json").read_text())["frames"][1]["views_trimmed"] == [names[0], names[2]]
    assert list(pq.read_table(tmp_path / "t.parquet")["views_reindexed"].to_pylist()) == ["", "", names[1]] + [""] * 3
    assert [f["views_reindexed"] for f in json.loads((tmp_path / "t.json").read_text())["frames"]][1:3] == [[], [names[1]]]


def test_infer_png_folders_with_missing_views(trained, dataset, tmp_path):
    model_path, _ = trained
    model = load_model(model_path)
    test = load_split(dataset, "test", with_masks=True)
    names = model.rig_.names
    folder = tmp_path / "pngs"
    for k, name in enumerate(names):
        if k == 3:
            continue  # a whole camera missing
        (folder / name).mkdir(parents=True)
        for i in range(len(test)):
            if k == 1 and i == 2:
                continue  # one frame missing in one camera
            cv2.imwrite(str(folder / name / f"frame{i:03d}.png"), test.masks[i, k] * 255)
    out = tmp_path / "png.parquet"
    res = _invoke("infer", model_path, folder, "--out", out)
    assert res.exit_code == 0, res.output
    table = pq.read_table(out).to_pandas()
    present = np.ones((6, 4), bool)
    present[:, 3] = False
    present[2, 1] = False
    # the dataset's contours come from the same masks
    ref = model.infer(test.contours, present, hypotheses=3, robust=True, untangle=True)
    got = np.stack([table[[f"{j}_x", f"{j}_y", f"{j}_z"]].to_numpy() for j in JOINT_NAMES], axis=1)
    np.testing.assert_allclose(got, single_answer(ref.joints, ref.hypotheses), atol=1e-5)
    assert list(table["n_views_present"]) == [3, 3, 2, 3, 3, 3]


def test_infer_flags_garbage_frames_with_a_status_and_a_warning(trained, dataset, tmp_path):
    model_path, _ = trained
    model = load_model(model_path)
    test = load_split(dataset, "test", with_masks=True)
    folder = tmp_path / "garbage"
    h, w = test.masks.shape[2:]
    for k, name in enumerate(model.rig_.names):
        (folder / name).mkdir(parents=True)
        cv2.imwrite(str(folder / name / "a_person.png"), test.masks[0, k] * 255)
        cv2.imwrite(str(folder / name / "b_white.png"), np.full((h, w), 255, np.uint8))
        cv2.imwrite(str(folder / name / "c_black.png"), np.zeros((h, w), np.uint8))
    out = tmp_path / "g.parquet"
    res = _invoke("infer", model_path, folder, "--out", out)
    assert res.exit_code == 0, res.output
    table = pq.read_table(out).to_pandas()
    assert list(table["status"]) == ["ok", "implausible", "no silhouette"]
    assert table["plausibility"][1] < model.plausibility_.flag_percentile < table["plausibility"][0]
    assert np.isnan(table["l_wrist_x"][2]) and table["n_views_present"][2] == 0
    assert "warning: 1 of 3 frame(s) implausible" in res.stderr and "first: b_white" in res.stderr
    assert "warning: 1 of 3 frame(s) no usable silhouette" in res.stderr


def test_infer_errors(trained, dataset, tmp_path):
    model_path, _ = trained
    res = _invoke("infer", tmp_path / "nope.npz", dataset)
    assert res.exit_code == 2 and "no such model file" in res.output
    empty = tmp_path / "empty"
    empty.mkdir()
    res = _invoke("infer", model_path, empty, "--out", tmp_path / "x.parquet")
    assert res.exit_code == 2 and "neither a dataset" in res.output and "cam" in res.output
    res = _invoke("infer", model_path, dataset, "--out", tmp_path / "x.csv")
    assert res.exit_code == 2 and ".parquet or .json" in res.output
    res = _invoke("infer", model_path, dataset, "--split", "valid", "--out", tmp_path / "x.json")
    assert res.exit_code == 2 and "no shards of split 'valid'" in res.output
    bad = tmp_path / "bad" / load_model(model_path).rig_.names[0]
    bad.mkdir(parents=True)
    cv2.imwrite(str(bad / "f.png"), np.zeros((10, 12), np.uint8))
    res = _invoke("infer", model_path, bad.parent, "--out", tmp_path / "x.json")
    assert res.exit_code == 2 and "f.png: image is 12x10" in res.output


def test_train_errors_and_select(dataset, tmp_path):
    res = _invoke("train", "no-such-preset", "--data-root", tmp_path)
    assert res.exit_code == 2 and "no dataset folder for preset 'no-such-preset'" in res.output
    res = _invoke("train", dataset, "--views", "a,b", "--out", tmp_path / "m.npz")
    assert res.exit_code == 2 and "--views" in res.output
    # --select with M, q and w fixed searches the noise variance only: one fit, one row per noise value
    out = tmp_path / "sel.npz"
    res = _invoke("train", dataset, "--select", "-M", "1", "-q", "3", "--structure-weight", "2", "--n-init", "1",
                  "--max-iter", "20", "--no-progress", "--out", out)
    assert res.exit_code == 0, res.output
    report = json.loads(out.with_suffix(".report.json").read_text())
    rows = report["selection"]["rows"]
    assert len(rows) == len(DEFAULT_GRID["noise_variance"]) and {r["n_latent"] for r in rows} == {3}
    assert report["hyperparameters"]["noise_variance"] == report["selection"]["best"]["noise_variance"]
    assert "Model selection" in out.with_suffix(".report.md").read_text()


def test_roughness_adds_ragged_copies_of_the_fitted_rows(dataset, tmp_path):
    out = tmp_path / "rough.npz"
    res = _invoke("train", dataset, "-M", "1", "-q", "3", "--n-init", "1", "--max-iter", "5", "--no-progress",
                  "--roughness", "0.5", "--roughness-copies", "2", "--mirror", "off", "--out", out)
    assert res.exit_code == 0, res.output
    report = json.loads(out.with_suffix(".report.json").read_text())
    assert report["n_fit"] == 72 and report["em"]["n_fit_rows"] == 3 * 72
    assert report["roughness"]["amplitude_px"] == 0.5 and report["roughness"]["copies"] == 2
    assert read_header(out)["training_config"]["roughness"]["copies"] == 2
    # the same model by hand: clean rows, then copies from streams seed + 0 and seed + 1 (sample ids = row indices)
    data = load_split(dataset, "train")
    fit_idx, _ = validation_split(80, 0.1, 0)
    c = np.asarray(data.contours[fit_idx], np.float64)
    spec = Roughness(amplitude_px=0.5, copies=2)
    rows = np.concatenate([c, roughen_contours(c, spec, 0, fit_idx), roughen_contours(c, spec, 1, fit_idx)])
    model = load_model(out)
    ref = type(model)(**{k: v for k, v in model.get_params().items()}).fit(
        rows, np.concatenate([data.joints[fit_idx]] * 3), rig=data.rig)
    np.testing.assert_allclose(ref.mixture_.means_, model.mixture_.means_, rtol=1e-9, atol=1e-9)
    res = _invoke("train", dataset, "--roughness", "1", "--streaming", "--out", tmp_path / "s.npz")
    assert res.exit_code == 2 and "--roughness" in res.output


def test_mirror_modes(dataset, tmp_path):
    """--mirror auto adds the default rig's mirrored people (see also test_train_writes_model_and_report),
    off adds none, on refuses a rig without a symmetry and streaming."""
    common = ["-M", "1", "-q", "3", "--n-init", "1", "--max-iter", "3", "--no-progress", "--roughness", "0"]
    res = _invoke("train", dataset, *common, "--mirror", "off", "--out", tmp_path / "off.npz")
    assert res.exit_code == 0, res.output
    report = json.loads((tmp_path / "off.report.json").read_text())
    assert report["mirrors"] == [] and report["em"]["n_fit_rows"] == 72
    res = _invoke("train", dataset, *common, "--mirror", "on", "--out", tmp_path / "on.npz")
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "on.report.json").read_text())["em"]["n_fit_rows"] == 2 * 72
    res = _invoke("train", dataset, *common, "--mirror", "on", "--streaming", "--out", tmp_path / "s.npz")
    assert res.exit_code == 2 and "--mirror on" in res.output
    res = _invoke("train", dataset, *common, "--mirror", "sometimes", "--out", tmp_path / "x.npz")
    assert res.exit_code == 2 and "--mirror must be one of" in res.output
    # a rig one camera of which moved 1 cm has no symmetry: auto adds nothing, on is an error
    asym = tmp_path / "asym"
    asym.mkdir()
    cams = list(default_rig().cameras)
    cams[1] = dataclasses.replace(cams[1], t=cams[1].t + np.array([0.01, 0, 0]))
    rig = Rig(tuple(cams))
    config = {"name": "asym", "seed": 3, "rig": rig.to_dict(), "n_points": N_POINTS}
    meta = build_metadata(rig.to_dict()["cameras"], config, N_POINTS, generator_version="test")
    write_shard(asym / "train-00000-of-00001.parquet", [synthetic_record(config, "train", i) for i in range(40)], meta)
    (asym / "manifest.json").write_text(json.dumps({"name": "asym"}))
    res = _invoke("train", asym, *common, "--out", tmp_path / "asym.npz")
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "asym.report.json").read_text())["mirrors"] == []
    res = _invoke("train", asym, *common, "--mirror", "on", "--out", tmp_path / "asym.npz")
    assert res.exit_code == 2 and "no mirror symmetry" in res.output
    # auto leaves the mirrors out above AUTO_MIRROR_MAX_ROWS (the paper preset's 18,000) and when streaming,
    # and says so in the report's notes
    from silpose.app.training import AUTO_MIRROR_MAX_ROWS, choose_mirrors
    ring = ring_rig(n_cameras=8, azimuth_step_deg=45.0)
    assert choose_mirrors(default_rig(), "auto", 1800, False) == (tuple(rig_mirrors(default_rig())), "")
    used, note = choose_mirrors(ring, "auto", AUTO_MIRROR_MAX_ROWS // 4, False)
    assert len(used) == 3 and "3 of the rig's 8 mirror symmetries used" in note
    assert choose_mirrors(default_rig(), "auto", 18000, False)[0] == ()
    assert "not added when streaming" in choose_mirrors(default_rig(), "auto", 100, True)[1]
    assert choose_mirrors(rig, "auto", 100, False) == ((), "")


def test_defaults_are_lowered_for_a_small_dataset(dataset, tmp_path):
    """With fewer than MIN_ROWS_PER_LATENT samples per component per latent dimension EM cannot move from
    its start: the trainer lowers M (to at least 10), then q; what the user fixes stays."""
    from silpose.app.training import MIN_ROWS_PER_LATENT, supported_size
    from silpose.model.shape_model import DEFAULT_N_COMPONENTS, DEFAULT_N_LATENT

    assert MIN_ROWS_PER_LATENT == 6
    assert supported_size(18000, 20, 40) == (20, 40) and supported_size(4800, 20, 40) == (20, 40)
    assert supported_size(1800, 20, 40) == (10, 30)  # the default preset: 1,800 / (6 * 10) = 30
    assert supported_size(1800, 20, 40, fixed_q=True) == (7, 40)
    assert supported_size(1800, 20, 40, fixed_m=True) == (20, 15)
    assert supported_size(100, 2, 4, fixed_m=True, fixed_q=True) == (2, 4)
    # the shipped defaults on the two presets' fitted sizes: paper keeps them, default gets M 10, q 30
    assert supported_size(18000, DEFAULT_N_COMPONENTS, DEFAULT_N_LATENT) == (DEFAULT_N_COMPONENTS, DEFAULT_N_LATENT)
    assert supported_size(1800, DEFAULT_N_COMPONENTS, DEFAULT_N_LATENT) == (10, 30)
    assert supported_size(5000, DEFAULT_N_COMPONENTS, DEFAULT_N_LATENT) == (20, 40)
    out = tmp_path / "small.npz"
    res = _invoke("train", dataset, "--n-init", "1", "--max-iter", "10", "--no-progress", "--out", out)
    assert res.exit_code == 0, res.output
    # 72 fitted samples and their 72 mirrored people (the default rig is mirror-symmetric)
    m, q = supported_size(144, DEFAULT_N_COMPONENTS, DEFAULT_N_LATENT)
    assert (m, q) == (10, 2) and "(with their 72 mirrored people)" in res.output
    assert f"lowered from the defaults {DEFAULT_N_COMPONENTS}, {DEFAULT_N_LATENT} to {m}, {q}" in res.output
    hp = read_header(out)["hyperparameters"]
    assert (hp["n_components"], hp["n_latent"]) == (m, q)
    assert "note: M, q lowered" in out.with_suffix(".report.md").read_text()


def test_header_records_training_config_and_generator_config(trained):
    header = read_header(trained[0])
    assert header["training_config"]["heldout_fraction"] == 0.1 and header["training_config"]["select"] is False
    assert header["dataset"]["generator_config"]["name"] == "tiny"
    assert load_model(trained[0]).training_config_["seed"] == 0


def test_fits_pools_em_fits_and_reports_each(dataset, tmp_path):
    """--fits N: N EM fits from seeds seed..seed+N-1 pooled into one model file; the report lists every fit;
    with --streaming it is a one-line error."""
    out = tmp_path / "pooled.npz"
    res = _invoke("train", dataset, "-M", "2", "-q", "2", "--fits", "3", "--seed", "7", "--max-iter", "15",
                  "--no-progress", "--out", out)
    assert res.exit_code == 0, res.output
    header = read_header(out)
    assert header["hyperparameters"]["n_fits"] == 3 and header["arrays"]["weights"][1] == [6]
    report = json.loads(out.with_suffix(".report.json").read_text())
    assert len(report["em"]["pooled_runs"]) == 3
    assert "pooled: 3 EM fits from seeds 7..9" in out.with_suffix(".report.md").read_text()
    res = _invoke("train", dataset, "--fits", "2", "--streaming", "--no-progress", "--out", tmp_path / "s.npz")
    assert res.exit_code == 2 and "--fits" in res.output and "--streaming" in res.output


def test_a_dataset_config_train_table_sets_the_defaults(tmp_path):
    """A preset's ``[train]`` (stored in the dataset's config) gives M, q, the pooled fits and the structure weight
    unless the command line gives its own; streaming cannot pool, so it fits once and says so; a malformed entry is
    a one-line error."""
    data = write_dataset(tmp_path / "d", "trained",
                         train={"components": 3, "latent": 2, "fits": 2, "structure_weight": 7.5})
    common = ("--max-iter", "10", "--no-progress")
    res = _invoke("train", data, *common, "--out", tmp_path / "a.npz")
    assert res.exit_code == 0, res.output
    hp = read_header(tmp_path / "a.npz")["hyperparameters"]
    assert (hp["n_components"], hp["n_latent"], hp["n_fits"], hp["structure_weight"]) == (3, 2, 2, 7.5)
    assert "the dataset's [train] settings (components 3, latent 2, fits 2, structure_weight 7.5)" in res.output
    assert "lowered" not in res.output  # the preset's sizes count as chosen, like the user's
    res = _invoke("train", data, *common, "-M", "4", "--fits", "1", "--structure-weight", "2", "--out", tmp_path / "b.npz")
    assert res.exit_code == 0, res.output
    hp = read_header(tmp_path / "b.npz")["hyperparameters"]
    assert (hp["n_components"], hp["n_latent"], hp["n_fits"], hp["structure_weight"]) == (4, 2, 1, 2.0)
    res = _invoke("train", data, *common, "--streaming", "--out", tmp_path / "c.npz")
    assert res.exit_code == 0, res.output
    assert read_header(tmp_path / "c.npz")["hyperparameters"]["n_fits"] == 1
    assert "fits = 2 not used: pooled fits are made in memory" in res.output
    bad = write_dataset(tmp_path / "bad", "trained", train={"fits": 0})
    res = _invoke("train", bad, *common, "--out", tmp_path / "e.npz")
    assert res.exit_code != 0 and "config.train.fits' must be an integer >= 1" in res.output
    assert str(bad) in res.output and not (tmp_path / "e.npz").exists()
    bad_w = write_dataset(tmp_path / "bad_w", "trained", train={"structure_weight": -1.0})
    res = _invoke("train", bad_w, *common, "--out", tmp_path / "f.npz")
    assert res.exit_code != 0 and "config.train.structure_weight' must be a number > 0" in res.output
