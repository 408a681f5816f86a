"""Chance computed as defined; kNN / ridge against direct references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from silpose.shared import metrics
from silpose.eval.baselines import ChanceBaseline, ViewSubsetRegressor
from silpose.eval.experiments import view_subsets
from silpose.shared.skeleton import root_relative


def test_chance_draws_training_poses_uniformly_and_deterministically():
    rng = np.random.default_rng(0)
    train = rng.normal(0, 0.3, (7, 19, 3)) + rng.normal(0, 2, (7, 1, 3))  # world offsets
    ch = ChanceBaseline(random_state=3).fit(train)
    pred = ch.predict(7000)
    rr = root_relative(train)
    # every prediction is exactly one root-relative training pose
    match = np.array([np.flatnonzero(np.all(np.isclose(rr, p), axis=(1, 2))) for p in pred[:200]], dtype=object)
    assert all(len(m) == 1 for m in match)
    counts = np.bincount(ch.draw_indices(7000), minlength=7)
    assert counts.min() > 850 and counts.max() < 1150  # uniform (expected 1000 each)
    np.testing.assert_array_equal(pred, ChanceBaseline(random_state=3).fit(train).predict(7000))
    assert not np.array_equal(pred, ChanceBaseline(random_state=4).fit(train).predict(7000))
    # the documented stream, with its literal keys: SeedSequence([random_state, 29])
    want = np.random.default_rng(np.random.SeedSequence([3, 29])).integers(0, 7, size=7000)
    np.testing.assert_array_equal(ch.draw_indices(7000), want)


def test_chance_error_converges_to_mean_over_training_poses():
    rng = np.random.default_rng(1)
    train = rng.normal(0, 0.3, (5, 19, 3))
    test = rng.normal(0, 0.3, (1, 19, 3))
    ch = ChanceBaseline(random_state=0).fit(train)
    err = metrics.pose_error_cm(ch.predict(20000), np.repeat(test, 20000, axis=0)).mean()
    exact = np.mean([metrics.pose_error_cm(t[None], test)[0] for t in train])  # expectation under uniform draws
    assert err == pytest.approx(exact, rel=0.02)


def test_knn_with_one_neighbour_returns_the_nearest_training_pose():
    rng = np.random.default_rng(2)
    x_train = rng.normal(size=(50, 4, 10, 2))
    y_train = rng.normal(size=(50, 19, 3))
    x_test = rng.normal(size=(6, 4, 10, 2))
    reg = ViewSubsetRegressor("knn", (2, 0), n_neighbors=1).fit(x_train, y_train)
    nearest = cdist(x_test[:, [0, 2]].reshape(6, -1), x_train[:, [0, 2]].reshape(50, -1)).argmin(axis=1)
    np.testing.assert_allclose(reg.predict(x_test), root_relative(y_train)[nearest], atol=1e-12)
    # only the subset's views are read
    x_test2 = x_test.copy()
    x_test2[:, [1, 3]] = 99.0
    np.testing.assert_array_equal(reg.predict(x_test2), reg.predict(x_test))


def test_ridge_equals_closed_form_with_the_chosen_penalty():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(80, 2, 6, 2))
    y = rng.normal(size=(80, 19, 3))
    reg = ViewSubsetRegressor("ridge", (1,)).fit(x, y)
    alpha = reg.estimator_.alpha_
    X = x[:, 1].reshape(80, -1)
    Y = root_relative(y).reshape(80, -1)
    xm, ym = X.mean(0), Y.mean(0)
    B = np.linalg.solve((X - xm).T @ (X - xm) + alpha * np.eye(X.shape[1]), (X - xm).T @ (Y - ym))
    xt = rng.normal(size=(3, 2, 6, 2))
    ref = (xt[:, 1].reshape(3, -1) - xm) @ B + ym
    np.testing.assert_allclose(reg.predict(xt).reshape(3, -1), ref, atol=1e-8)
    with pytest.raises(ValueError, match="kind"):
        ViewSubsetRegressor("forest", (0,)).fit(x, y)


def test_view_subsets_cover_every_combination():
    s = view_subsets(4)
    assert len(s) == 15 and len(set(s)) == 15
    assert [len(v) for v in s].count(3) == 4 and [len(v) for v in s].count(2) == 6 and [len(v) for v in s].count(1) == 4


def test_size_factors_scale_targets_and_predictions():
    """With size= the regressor learns joints / size and returns prediction * size: 1-NN returns the
    nearest training pose rescaled from its walker's size to the test walker's."""
    rng = np.random.default_rng(4)
    x_train = rng.normal(size=(30, 2, 5, 2))
    y_train = rng.normal(size=(30, 19, 3))
    s_train = rng.uniform(0.8, 1.2, 30)
    x_test = rng.normal(size=(4, 2, 5, 2))
    s_test = rng.uniform(0.8, 1.2, 4)
    reg = ViewSubsetRegressor("knn", (0, 1), n_neighbors=1).fit(x_train, y_train, size=s_train)
    nearest = cdist(x_test.reshape(4, -1), x_train.reshape(30, -1)).argmin(axis=1)
    want = root_relative(y_train)[nearest] / s_train[nearest, None, None] * s_test[:, None, None]
    np.testing.assert_allclose(reg.predict(x_test, size=s_test), want, atol=1e-12)


# ----------------------------------------------------------------------------- the MLP baseline
from silpose.eval.baselines import MLPSettings, ViewDropoutMLP, fit_mlp, group_split, masked_features  # noqa: E402
from silpose.eval.experiments import walker_groups  # noqa: E402

_SMALL_MLP = MLPSettings(hidden=(64, 64), max_epochs=150, patience=15, batch_size=64, learning_rate=3e-3)


def test_group_split_never_puts_a_walker_on_both_sides():
    groups = np.repeat(np.arange(50), 6)  # a walker's clean, noisy and mirrored copies
    np.random.default_rng(0).shuffle(groups)
    tr, va = group_split(groups, 0.2, random_state=1)
    assert len(tr) + len(va) == len(groups) and len(np.intersect1d(tr, va)) == 0
    assert set(groups[tr]).isdisjoint(groups[va])
    assert 0.1 < len(set(groups[va])) / 50 < 0.3


def test_mlp_beats_ridge_on_a_nonlinear_map_and_splits_by_walker():
    """y = sin(3 x0) x1 + |x2| is nonlinear: the MLP's held-out error is well below ridge's; the rows it
    validated on belong to walkers it did not train on."""
    rng = np.random.default_rng(0)
    n_walkers, copies = 300, 3
    base = rng.uniform(-1, 1, (n_walkers, 4))
    x = np.concatenate([base + 0.02 * rng.standard_normal(base.shape) for _ in range(copies)])
    groups = np.tile(np.arange(n_walkers), copies)

    def target(v):
        return np.stack([np.sin(3 * v[:, 0]) * v[:, 1] + np.abs(v[:, 2]), v[:, 3] ** 2], axis=1)

    y = target(x)
    mlp = fit_mlp(x, y, groups, _SMALL_MLP)
    assert set(groups[mlp.train_rows_]).isdisjoint(groups[mlp.val_rows_])
    xt = rng.uniform(-1, 1, (500, 4))
    err_mlp = np.sqrt(np.mean((mlp.predict(xt) - target(xt)) ** 2))
    from sklearn.linear_model import RidgeCV

    err_ridge = np.sqrt(np.mean((RidgeCV().fit(x, y).predict(xt) - target(xt)) ** 2))
    assert err_mlp < 0.5 * err_ridge
    assert 1 <= mlp.best_epoch_ <= mlp.n_epochs_ <= _SMALL_MLP.max_epochs


def test_mlp_inputs_are_scaled_by_one_global_factor():
    """Features with very different spreads keep their ratio after scaling (no per-feature standardisation)."""
    rng = np.random.default_rng(1)
    x = rng.standard_normal((200, 3)) * np.array([10.0, 1.0, 0.01])
    y = x[:, :2]
    mlp = fit_mlp(x, y, np.arange(200), MLPSettings(hidden=(8,), max_epochs=2, patience=1, batch_size=32))
    assert np.ndim(mlp.x_scale_) == 0
    tr = mlp.train_rows_
    assert mlp.x_scale_ == pytest.approx(np.sqrt(np.mean((x[tr] - x[tr].mean(axis=0)) ** 2)))


def test_masked_features_zero_absent_views_and_flag_them():
    c = np.arange(2 * 3 * 4 * 2, dtype=float).reshape(2, 3, 4, 2) + 1
    present = np.array([[True, False, True], [False, True, False]])
    f = masked_features(c, present)
    assert f.shape == (2, 3 * 8 + 3)
    np.testing.assert_array_equal(f[:, -3:], present.astype(float))
    body = f[:, :-3].reshape(2, 3, 8)
    np.testing.assert_array_equal(body[~present], 0.0)
    np.testing.assert_array_equal(body[present], c.reshape(2, 3, 8)[present])


def test_view_dropout_mlp_predicts_joints_from_any_subset():
    """Joints that are a linear function of view 0's contour: the MLP given view 0 (alone or with others) is
    far closer than given view 1 alone, which carries no information."""
    rng = np.random.default_rng(2)
    n = 400
    c = rng.standard_normal((n, 2, 3, 2))
    A = rng.standard_normal((6, 57)) * 0.05
    joints = (c[:, 0].reshape(n, 6) @ A).reshape(n, 19, 3)
    present = rng.random((n, 2)) < 0.7
    present[~present.any(axis=1), 0] = True
    reg = ViewDropoutMLP(_SMALL_MLP).fit(c, present, joints, np.arange(n))
    truth = root_relative(joints)
    err = {v: metrics.pose_error_cm(reg.predict(c, v), truth).mean() for v in ((0,), (1,), (0, 1))}
    assert err[(0,)] < 0.5 * err[(1,)] and err[(0, 1)] < 0.5 * err[(1,)]


def test_walker_groups_join_rows_with_equal_subject_parameters():
    subject = {"height": np.array([1.7, 1.8, 1.7, 1.7]), "skirt": np.array([np.nan, 0.2, np.nan, 0.3])}
    g = walker_groups(subject, 4)
    assert g[0] == g[2] and len({g[0], g[1], g[3]}) == 3
    np.testing.assert_array_equal(walker_groups({}, 3), np.arange(3))
