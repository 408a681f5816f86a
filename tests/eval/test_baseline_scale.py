"""The baselines at scale: the blocked ridge against scikit-learn, the seeded row cap, the float32 MLP inputs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import sklearn
from sklearn.linear_model import Ridge, RidgeCV

from silpose.eval.baselines import RIDGE_ALPHAS, MLPSettings, ViewDropoutMLP, fit_mlp, masked_features
from silpose.eval import experiments
from silpose.eval.experiments import EvalConfig, EvalData, Evaluation
from silpose.eval.ridge import BlockRidgeCV
from silpose.shared.contours import normalise
from silpose.shared.seeds import BASELINE_ROWS_STREAM, draw_subset
from silpose.shared.skeleton import root_relative


def _cv_kwargs() -> dict:
    new = tuple(int(v) for v in sklearn.__version__.split(".")[:2]) >= (1, 5)
    return {"store_cv_results": True} if new else {"store_cv_values": True}


@pytest.mark.parametrize("n, p", [(230, 30), (40, 70)])  # more rows than features, and fewer
def test_block_ridge_equals_sklearn_ridgecv(n, p):
    """Same leave-one-out errors per penalty, same penalty, same coefficients as RidgeCV (its own SVD / Gram
    path) on the same rows, with blocks much smaller than the data and rows far from the origin."""
    rng = np.random.default_rng(n)
    x = rng.normal(size=(n, p)) * rng.uniform(0.1, 2.0, p) + 5.0
    y = x @ rng.normal(size=(p, 4)) * 0.3 + rng.normal(size=(n, 4)) + np.array([1.0, -2.0, 0.0, 7.0])
    ref = RidgeCV(alphas=RIDGE_ALPHAS, **_cv_kwargs()).fit(x, y)
    got = BlockRidgeCV(RIDGE_ALPHAS, block_rows=17).fit(x, y)
    cv = getattr(ref, "cv_results_", None)
    cv = ref.cv_values_ if cv is None else cv
    np.testing.assert_allclose(got.loo_mse_, cv.mean(axis=(0, 1)), rtol=1e-8)
    assert got.alpha_ == ref.alpha_ and RIDGE_ALPHAS[0] < got.alpha_ < RIDGE_ALPHAS[-1]  # an interior choice
    np.testing.assert_allclose(got.coef_, ref.coef_, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(got.intercept_, ref.intercept_, rtol=1e-8, atol=1e-9)
    xt = rng.normal(size=(5, p)) + 5.0
    np.testing.assert_allclose(got.predict(xt), Ridge(alpha=got.alpha_).fit(x, y).predict(xt), rtol=1e-8, atol=1e-9)


def test_draw_subset_is_seeded_sorted_and_capped():
    idx = draw_subset(1000, 100, 3, BASELINE_ROWS_STREAM)
    assert len(idx) == 100 and np.all(np.diff(idx) > 0) and idx[-1] < 1000
    want = np.sort(np.random.default_rng(np.random.SeedSequence([3, BASELINE_ROWS_STREAM])).choice(1000, 100, replace=False))
    np.testing.assert_array_equal(idx, want)
    assert not np.array_equal(idx, draw_subset(1000, 100, 4, BASELINE_ROWS_STREAM))
    np.testing.assert_array_equal(draw_subset(50, 100, 3), np.arange(50))
    np.testing.assert_array_equal(draw_subset(50, None, 3), np.arange(50))


def _evaluation(n_train: int, cap: int | None) -> Evaluation:
    rng = np.random.default_rng(7)
    K, P = 3, 12
    ring = np.stack([np.cos(np.linspace(0, 2 * np.pi, P, endpoint=False)),
                     np.sin(np.linspace(0, 2 * np.pi, P, endpoint=False))], axis=1)
    train = 100 + 30 * ring[None, None] * rng.uniform(0.8, 1.2, (n_train, K, P, 1)) + rng.normal(0, 2, (n_train, K, P, 2))
    data = EvalData(train_contours=train, train_joints=rng.normal(0, 0.3, (n_train, 19, 3)),
                    test_ids=np.arange(4), test_joints=np.zeros((4, 19, 3)), test_contours=train[:4],
                    test_centroid=np.zeros((4, K, 2)), test_scale=np.ones((4, K)), image_size=np.full((K, 2), 240),
                    train_groups=np.arange(n_train) // 2)
    return Evaluation(data=data, model=SimpleNamespace(), config=EvalConfig(baseline_rows=cap, seed=3))


def test_capped_ridge_equals_sklearn_on_the_drawn_rows():
    ev = _evaluation(300, cap=120)
    rows = ev.baseline_rows()
    np.testing.assert_array_equal(rows, draw_subset(300, 120, 3, BASELINE_ROWS_STREAM))
    assert ev.extra["baseline_rows"] == {"cap": 120, "rows": 120, "of": 300}
    reg = ev.regressor("ridge", (0, 2))
    norm = normalise(ev.data.train_contours[rows])[0][:, [0, 2]].reshape(120, -1)
    x = norm.astype(np.float32).astype(np.float64)  # the baseline's float32 rows
    y = root_relative(ev.data.train_joints[rows]).reshape(120, -1)
    ref = RidgeCV(alphas=RIDGE_ALPHAS).fit(x, y)
    assert reg.estimator_.alpha_ == ref.alpha_
    np.testing.assert_allclose(reg.estimator_.coef_, ref.coef_, rtol=1e-7, atol=1e-9)
    knn = ev.regressor("knn", (0, 2))  # kNN keeps every training sample
    assert knn.estimator_.n_samples_fit_ == 300 and knn.estimator_._fit_X.dtype == np.float32


def test_masked_features_gather_rows_in_float32():
    rng = np.random.default_rng(4)
    c = rng.normal(size=(9, 3, 4, 2))
    c[1, 2] = np.nan  # an absent view may hold anything
    present = rng.random((9, 3)) < 0.6
    present[1, 2] = False
    order = np.array([4, 0, 8, 1])
    f = masked_features(c, present, rows=order)
    assert f.dtype == np.float32 and f.shape == (4, 3 * 8 + 3)
    ref = np.concatenate([np.where(present[:, :, None, None], c, 0.0).reshape(9, -1), present], axis=1)[order]
    np.testing.assert_array_equal(f, ref.astype(np.float32))


def test_mlp_in_place_scaling_equals_the_copying_fit():
    """ViewDropoutMLP's ordered, overwritten inputs give the network fit_mlp gives on a plain copy; the split
    is reported in the caller's row numbers."""
    rng = np.random.default_rng(5)
    n = 120
    c = rng.normal(size=(n, 2, 3, 2))
    present = np.ones((n, 2), bool)
    joints = rng.normal(0, 0.2, (n, 19, 3))
    groups = np.arange(n) // 3
    settings = MLPSettings(hidden=(16,), max_epochs=3, patience=3, batch_size=32)
    got = ViewDropoutMLP(settings).fit(c, present, joints, groups).estimator_
    x = masked_features(c, present)
    y = root_relative(joints).reshape(n, -1)
    ref = fit_mlp(x, y, groups, settings)
    np.testing.assert_array_equal(got.train_rows_, ref.train_rows_)
    np.testing.assert_allclose(got.x_mean_, ref.x_mean_, rtol=1e-12)
    assert got.x_scale_ == pytest.approx(ref.x_scale_, rel=1e-12)
    for a, b in zip(got.net_.coefs_, ref.net_.coefs_):
        np.testing.assert_array_equal(a, b)
    assert np.array_equal(x, masked_features(c, present))  # fit_mlp left the caller's array alone


def test_evaluation_mlp_is_the_view_dropout_mlp_on_the_capped_rows(monkeypatch):
    """The eval builds the MLP's float32 rows in place, copy by copy; the network equals ViewDropoutMLP.fit on the
    same capped samples, noisy copies and view subsets assembled the plain way."""
    from silpose.eval.noise import NoiseSpec, apply_noise
    from silpose.shared.seeds import BASELINE_AUGMENT_STREAM, derive_rng

    monkeypatch.setattr(experiments, "_NORM_BLOCK", 16)  # several blocks of rows per copy
    ev = _evaluation(90, cap=40)
    ev.config.noise = NoiseSpec(label="jitter", jitter_px=1.0)
    ev.config.mlp = MLPSettings(hidden=(16,), max_epochs=3, patience=3, batch_size=16)
    got = ev.mlp_baseline().estimator_
    rows, d, K = ev.baseline_rows(), ev.data, ev.data.n_views
    rng = derive_rng(ev.config.seed, BASELINE_AUGMENT_STREAM)
    seeds = [int(rng.integers(2**31 - 1)) for _ in range(ev.config.mlp_noisy_copies)]
    px = [d.train_contours[rows]] + [apply_noise(ev.config.noise, d.train_contours[rows], rows, s) for s in seeds]
    px = np.concatenate(px)
    present = np.zeros((len(px), K), bool)
    for r, k in enumerate(rng.integers(1, K + 1, size=len(px))):
        present[r, rng.choice(K, size=k, replace=False)] = True
    reps = len(px) // len(rows)
    ref = ViewDropoutMLP(ev.config.mlp).fit(normalise(px)[0], present, np.concatenate([d.train_joints[rows]] * reps),
                                            np.tile(d.train_groups[rows], reps)).estimator_
    assert ev.extra["mlp_baseline"]["rows"] == 3 * 40
    for a, b in zip(got.net_.coefs_, ref.net_.coefs_):
        np.testing.assert_array_equal(a, b)
