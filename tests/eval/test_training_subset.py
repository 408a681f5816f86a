"""E1/E4 train their extra models on exactly the samples `silpose train` fitted the 4-view model on."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.eval.run import match_training_subset, load_data
from silpose.model.persistence import load_model
from silpose.model.shape_model import ShapeStructureModel
from silpose.app.training import run_training


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
