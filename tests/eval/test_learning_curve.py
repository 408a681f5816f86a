"""The learning-curve tool: nested training sets, its points scored like the rest of eval, the in-memory and
out-of-core fits of one point agreeing."""

import json

import numpy as np

from silpose.eval import learning_curve
from silpose.shared.dataset import load_split


def test_training_rows_are_nested_and_sorted(stick_dataset):
    small, large = learning_curve.training_rows(stick_dataset, 30), learning_curve.training_rows(stick_dataset, 90)
    assert np.all(np.diff(large) > 0) and len(small) == 30
    assert set(small) <= set(large)


def test_in_memory_point_equals_the_out_of_core_point(stick_dataset):
    test = load_split(stick_dataset, "test")
    joints = np.asarray(test.joints, np.float64)
    contours = np.asarray(test.contours, np.float64)
    train = load_split(stick_dataset, "train", columns=["joints", "contours"])
    kw = dict(seed=0, max_iter=5, tol=1e-3)
    mem = learning_curve.curve_point(stick_dataset, joints, contours, 60, 2, 3, train=train, **kw)
    ooc = learning_curve.curve_point(stick_dataset, joints, contours, 60, 2, 3, train=None, **kw)
    assert mem["n_samples"] == ooc["n_samples"] == 60 and mem["n_iter"] == ooc["n_iter"]
    assert abs(mem["pose_all_views_cm"] - ooc["pose_all_views_cm"]) < 1e-3 * ooc["pose_all_views_cm"]
    assert abs(mem["pose_1_view_cm"] - ooc["pose_1_view_cm"]) < 1e-3 * ooc["pose_1_view_cm"]
    assert 0 < mem["pose_all_views_cm"] < mem["pose_1_view_cm"] * 1.5  # cm, not metres


def test_main_writes_every_point(stick_dataset, tmp_path):
    assert learning_curve.main([str(stick_dataset), "--n", "40", "80", "--m", "2", "--q", "2", "--max-iter", "3",
                                "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "learning_curve.json").read_text())
    assert [(r["n_samples"], r["n_components"]) for r in data["rows"]] == [(40, 2), (80, 2)]
    assert data["settings"]["fit"] == "in memory"
    assert (tmp_path / "learning_curve.csv").read_text().count("\n") == 3


def test_the_structure_weight_reaches_the_fits(stick_dataset, tmp_path):
    """Without [train] in the dataset the model's default weight is used; --structure-weight changes the fits."""
    common = [str(stick_dataset), "--n", "80", "--m", "2", "--q", "2", "--max-iter", "3"]
    assert learning_curve.main(common + ["--out", str(tmp_path / "a")]) == 0
    assert learning_curve.main(common + ["--structure-weight", "3", "--out", str(tmp_path / "b")]) == 0
    a, b = (json.loads((tmp_path / x / "learning_curve.json").read_text()) for x in ("a", "b"))
    assert a["settings"]["structure_weight"] == 30.0 and b["settings"]["structure_weight"] == 3.0
    assert a["rows"][0]["pose_all_views_cm"] != b["rows"][0]["pose_all_views_cm"]
