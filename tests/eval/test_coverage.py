"""Pose coverage (``silpose.eval.coverage``): the nearest training pose of every test pose.

Reference: a per-sample loop over the training poses in float64.
"""

from __future__ import annotations

import json

import numpy as np

from silpose.eval import coverage as cov
from silpose.shared.dataset import load_split


def test_nearest_pose_is_the_smallest_mean_joint_distance_across_blocks(monkeypatch):
    rng = np.random.default_rng(0)
    train, test = rng.normal(size=(300, 19, 3)), rng.normal(size=(11, 19, 3))
    monkeypatch.setattr(cov, "BLOCK", 4)  # several blocks and a partial last one
    idx, err = cov.nearest_pose(test, train)
    for t, i, e in zip(test, idx, err):  # brute force, one test pose at a time, in float64
        d = np.linalg.norm(train - t, axis=2).mean(axis=1)
        assert i == np.argmin(d) and abs(e - 100 * d.min()) < 1e-4


def test_coverage_of_the_stick_dataset_is_the_nearest_training_poses_error(stick_dataset, tmp_path):
    res = cov.coverage(stick_dataset)
    tr = load_split(stick_dataset, "train", columns=["joints"]).joints
    te = load_split(stick_dataset, "test", columns=["joints"]).joints
    tr, te = tr - tr[:, :1], te - te[:, :1]
    per = [min(100 * np.linalg.norm(t - u, axis=1).mean() for u in tr) for t in te]  # the smallest error, brute force
    assert res["n_test"] == len(te) and res["n_train"] == len(tr)
    assert abs(res["mean_cm"] - np.mean(per)) < 1e-4
    assert res["mean_cm"] > 0 and "groups" not in res  # the stick figures come from no grouped clips
    assert cov.main([str(stick_dataset), "--out", str(tmp_path / "c.json")]) == 0
    assert json.loads((tmp_path / "c.json").read_text())["mean_cm"] == res["mean_cm"]
