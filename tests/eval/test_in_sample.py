"""The model on samples it was fitted on (``silpose.eval.in_sample``): only fitted rows are drawn, and the
figures are the paper's pose error of ``silpose infer``'s default answer, recomputed here."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.app.training import run_training
from silpose.eval.experiments import EvalConfig, Evaluation
from silpose.eval.in_sample import NOISE_ID_OFFSET, in_sample_error
from silpose.eval.noise import apply_noise
from silpose.eval.run import load_data, match_training_subset
from silpose.model.persistence import load_model
from silpose.shared.contours import normalise

pytestmark = pytest.mark.filterwarnings("ignore:MPPCA. EM did not converge")


@pytest.fixture(scope="module")
def evaluation(stick_dataset, tmp_path_factory):
    """A model fitted by ``silpose train`` with a quarter of the stick dataset held out, and its evaluation."""
    out = tmp_path_factory.mktemp("in_sample") / "m.npz"
    run_training(str(stick_dataset), out=out, n_components=6, n_latent=4, max_iter=30, n_init=1, tol=1e-3,
                 progress=False, roughness=None, mirror="off", heldout=0.25)
    model = load_model(out)
    data = load_data(stick_dataset, None, with_masks=False)
    all_joints = data.train_joints.copy()
    match_training_subset(data, model)
    return Evaluation(data=data, model=model, config=EvalConfig()), all_joints


def test_only_fitted_samples_are_drawn_and_their_error_is_recomputable(evaluation):
    ev, all_joints = evaluation
    d = ev.data
    res = in_sample_error(ev)
    rows = np.asarray(res["rows"])
    assert res["n"] == len(rows) == len(d.test_ids) and np.all(np.diff(rows) > 0)
    assert rows.max() < d.train_fitted < len(all_joints)
    # the drawn rows are samples the trainer fitted: none of them is a held-out sample of the split
    fit_rows = [np.flatnonzero((all_joints == j).all(axis=(1, 2))) for j in d.train_joints[:d.train_fitted]]
    held = np.setdiff1d(np.arange(len(all_joints)), np.concatenate(fit_rows))
    drawn = d.train_joints[rows]
    assert len(held) > 0 and not any((all_joints[h] == drawn).all(axis=(1, 2)).any() for h in held)
    # the same noise, the same inference, and the pose error recomputed with numpy from the joints
    clean = d.train_contours[rows]
    _, cen, sc = normalise(clean)
    noisy = apply_noise(ev.config.noise, clean, NOISE_ID_OFFSET + rows, ev.config.seed)
    pred = ev.model.infer(noisy, centroid=cen, scale=sc, robust=True).joints
    true = d.train_joints[rows]
    err = 100 * np.linalg.norm((pred - pred[:, :1]) - (true - true[:, :1]), axis=2).mean(axis=1)
    assert res["in_sample_mean_cm"] == pytest.approx(err.mean(), rel=1e-9)
    assert res["in_sample_median_cm"] == pytest.approx(np.median(err), rel=1e-9)
    assert in_sample_error(ev)["rows"] == res["rows"]  # a seeded draw


def test_no_figure_when_the_fitted_samples_are_unknown(evaluation):
    ev, _ = evaluation
    unknown = Evaluation(data=ev.data, model=ev.model, config=ev.config)
    saved, unknown.data.train_fitted = ev.data.train_fitted, None
    try:
        assert in_sample_error(unknown) is None
    finally:
        ev.data.train_fitted = saved
