"""The held-out part of ``silpose train`` (silpose.app.heldout): whole clips on a motion-capture dataset."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from silpose.app.heldout import clip_groups, heldout_split
from silpose.datagen.testing import write_synthetic_dataset
from silpose.shared.cli import build_app
from silpose.shared.dataset import load_split

pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")

N_POINTS = 16


def clip_of(i: int) -> int:
    """Row i's clip: every third row a procedural walk (0), the rest in runs of 8 rows per clip."""
    return 0 if i % 3 == 0 else 1 + i // 8


@pytest.fixture(scope="module")
def clip_dataset(tmp_path_factory):
    """80 train rows in two shards with ``gait.clip`` (:func:`clip_of`), 5 test rows."""
    return write_synthetic_dataset(tmp_path_factory.mktemp("data") / "clips", (40, 40), N_POINTS, name="clips",
                                   seed=3, clip_of=clip_of)


def test_walk_only_dataset_keeps_the_random_split(tmp_path):
    root = write_synthetic_dataset(tmp_path / "walk", (20, 20), N_POINTS)
    assert clip_groups(root) is None


def test_clip_groups_follow_the_rows(clip_dataset):
    groups = clip_groups(clip_dataset)
    clips = load_split(clip_dataset, "train", columns=["gait"]).gait["clip"].astype(int)
    assert groups.shape == (80,)
    np.testing.assert_array_equal(groups[clips > 0], clips[clips > 0])
    walk = groups[clips == 0]
    assert np.all(walk < 0) and len(np.unique(walk)) == walk.size  # every walk row its own group


def test_heldout_split_holds_out_whole_clips(clip_dataset):
    groups = clip_groups(clip_dataset)
    fit, held = heldout_split(80, 0.25, 0, groups)
    assert sorted(np.concatenate([fit, held]).tolist()) == list(range(80))
    shared = set(groups[fit]) & set(groups[held])
    assert not shared
    assert 10 <= held.size <= 30
    with pytest.raises(ValueError, match="groups has 3 entries for 80 rows"):
        heldout_split(80, 0.25, 0, groups[:3])


def test_train_reports_clip_heldout(clip_dataset, tmp_path):
    out = tmp_path / "m.npz"
    res = CliRunner().invoke(build_app(), ["train", str(clip_dataset), "-M", "2", "-q", "3", "--max-iter", "5",
                                           "--heldout", "0.25", "--out", str(out), "--no-progress",
                                           "--roughness", "0", "--mirror", "off"])
    assert res.exit_code == 0, res.output
    report = json.loads(out.with_suffix(".report.json").read_text())
    assert report["heldout_by"] == "clip"
    groups = clip_groups(clip_dataset)
    fit, held = heldout_split(80, 0.25, 0, groups)
    assert report["n_heldout"] == held.size and report["n_fit"] == fit.size
    assert "(whole clips)" in out.with_suffix(".report.md").read_text()
