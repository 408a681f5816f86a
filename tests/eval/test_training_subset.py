"""E1/E4 train their extra models on exactly the samples `silpose train` fitted the 4-view model on."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.eval.run import match_training_subset, load_data
from silpose.model.persistence import load_model
from silpose.model.shape_model import ShapeStructureModel
from silpose.app.heldout import clip_groups
from silpose.app.training import run_training
from silpose.datagen.testing import write_synthetic_dataset


@pytest.mark.filterwarnings("ignore:MPPCA. EM did not converge")
def test_subset_reproduces_the_trainers_fit(stick_dataset, tmp_path):
    run_training(str(stick_dataset), out=tmp_path / "m.npz", n_components=2, n_latent=3, max_iter=4, n_init=1,
                 tol=1e-3, progress=False)
    model = load_model(tmp_path / "m.npz")
    data = load_data(stick_dataset, None, with_masks=False)
    n_all = len(data.train_joints)
    note = match_training_subset(data, model)
    # the trainer's mirrored people (the stick rig is the default, mirror-symmetric one; mirror "auto") and
    # ragged copies (roughness "auto": one copy per sample) are reproduced too
    copies = model.training_config_["roughness"]["copies"]
    assert copies == 1 and "ragged copy" in note and "mirrored people (1 rig symmetry)" in note
    assert len(model.training_config_["mirrors"]) == 1
    n_fit = model.dataset_info_["n_fit"]
    assert len(data.train_joints) == 2 * (1 + copies) * n_fit and n_fit < n_all
    refit = ShapeStructureModel(**model.get_params()).fit(data.train_contours, data.train_joints, rig=data.rig)
    np.testing.assert_allclose(refit.mixture_.means_, model.mixture_.means_, rtol=1e-6, atol=1e-9)


def _clip_of(i: int) -> int:
    """Row i's clip: every third row a procedural walk (0), the rest in runs of 8 rows per clip."""
    return 0 if i % 3 == 0 else 1 + i // 8


@pytest.mark.filterwarnings("ignore:MPPCA. EM did not converge")
def test_subset_of_a_clip_dataset_leaves_out_the_trainers_whole_clips(tmp_path):
    """A motion-capture dataset's held-out part is whole clips (silpose.app.heldout); the evaluation must leave
    out those clips, not a random part of the rows of the same size."""
    root = write_synthetic_dataset(tmp_path / "clips", (40, 40), 16, name="clips", seed=3, clip_of=_clip_of)
    run_training(str(root), out=tmp_path / "m.npz", n_components=2, n_latent=3, max_iter=4, n_init=1, tol=1e-3,
                 progress=False, roughness=None, mirror="off", heldout=0.25)
    model = load_model(tmp_path / "m.npz")
    assert model.training_config_["heldout_by"] == "clip"
    data = load_data(root, None, with_masks=False)
    joints_all = data.train_joints.copy()
    note = match_training_subset(data, model, clip_groups(root, "train"))
    assert "reproduced" in note and data.train_fitted == model.dataset_info_["n_fit"] == len(data.train_joints)
    clips = np.array([_clip_of(i) for i in range(80)])
    kept = np.array([np.flatnonzero((joints_all == j).all(axis=(1, 2)))[0] for j in data.train_joints])
    held = np.setdiff1d(np.arange(80), kept)
    # every held-out clip is held out whole, and no fitted row shares a clip with a held-out one
    assert len(held) > 0 and not set(clips[held][clips[held] > 0]) & set(clips[kept][clips[kept] > 0])
    refit = ShapeStructureModel(**model.get_params()).fit(data.train_contours, data.train_joints, rig=data.rig)
    np.testing.assert_allclose(refit.mixture_.means_, model.mixture_.means_, rtol=1e-6, atol=1e-9)
