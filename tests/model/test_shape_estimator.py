"""ShapeStructureModel as a scikit-learn estimator (issue 13, item 5).

``get_params(deep)`` / ``set_params``, ``fit(X, y)`` with X the multi-view pixel contours (N, K, n, 2) and
y the joints, ``predict`` -> joints, ``score`` -> negative mean joint error (cm); ``clone``,
``GridSearchCV`` and ``cross_val_score`` work on it.

Estimator checks: scikit-learn's own API checks that do not fit on 2-D tabular data run as they are
(``SKLEARN_API_CHECKS``). The checks that fit on generated 2-D tables (``check_estimators_fit_returns_self``,
``check_estimators_overwrite_params``, ``check_dont_overwrite_parameters``, ``check_fit_idempotent``,
``check_methods_sample_order_invariance``, ``check_methods_subset_invariance``, ``check_estimators_nan_inf``,
``check_dict_unchanged``, ``check_readonly_memmap_input``, ``check_fit_score_takes_y``) cannot feed this
estimator, whose input is (N, K, n, 2) contours and whose target is 19 joints: each is re-run below on
contour data, with the same assertion (``test_check_*``). The estimator declares ``two_d_array = False``,
so ``parametrize_with_checks`` itself skips it; the checks about sample weights, sparse input, classifiers,
transformers, outlier detectors, pickling (silpose stores models as .npz, never pickle) and array API do
not apply.
"""

from __future__ import annotations

import inspect
import warnings

import joblib
import numpy as np
import pytest
from sklearn.base import clone, is_regressor
from sklearn.exceptions import ConvergenceWarning, NotFittedError
from sklearn.model_selection import GridSearchCV, KFold, cross_val_score
from sklearn.utils import estimator_checks as ec

from silpose.datagen.testing import synthetic_record
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.shared.camera import default_rig
from silpose.shared.skeleton import root_relative

N_POINTS = 16
SMALL = dict(n_components=2, n_latent=4, structure_weight=2.0, noise_variance=1e-4, n_init=1, max_iter=30,
             random_state=0)


@pytest.fixture(scope="module")
def data():
    d = make_linear_shapes(150, n_views=3, n_points=N_POINTS, seed=5)
    return d.contours.astype(np.float64), d.joints.astype(np.float64)


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        yield


def reference_error_cm(pred, joints):
    """Mean over samples and joints of the root-relative joint distance, cm (written out here)."""
    p = np.asarray(pred).reshape(-1, 19, 3)
    p = p - p[:, :1]
    t = joints - joints[:, :1]
    return float(np.mean(np.sqrt(((p - t) ** 2).sum(-1))) * 100)


# ------------------------------------------------------------------ parameters


def test_get_params_deep_and_set_params():
    est = ShapeStructureModel(**SMALL)
    params = est.get_params(deep=True)
    assert params == est.get_params(deep=False)  # no nested estimators
    assert set(params) == set(inspect.signature(ShapeStructureModel).parameters)
    assert params["structure_weight"] == 2.0 and params["callback"] is None and params["rig"] is None
    assert est.set_params(structure_weight=5.0, views=(0, 2)) is est
    assert est.structure_weight == 5.0 and est.views == (0, 2)
    with pytest.raises(ValueError, match="Invalid parameter 'nope'"):
        est.set_params(nope=1)
    assert is_regressor(est)


def test_hyperparameters_stay_the_json_record_of_model_files():
    hp = ShapeStructureModel(**SMALL, views=(0, 1)).hyperparameters()
    assert hp == {"n_components": 2, "n_latent": 4, "structure_weight": 2.0, "views": [0, 1], "noise_variance": 1e-4,
                  "joint_frame": None, "noise_dof": True, "tol": 1e-4, "max_iter": 30, "n_init": 1, "n_fits": 1,
                  "random_state": 0}


# ------------------------------------------------------------------ fit / predict / score


def test_fit_X_y_predict_and_score(data):
    X, y = data
    est = ShapeStructureModel(**SMALL).fit(X[:120], y[:120])
    pred = est.predict(X[120:])
    np.testing.assert_array_equal(pred, est.infer(X[120:]).joints)
    assert pred.shape == (30, 19, 3)
    assert est.score(X[120:], y[120:]) == pytest.approx(-reference_error_cm(pred, y[120:]), rel=1e-12)
    assert -est.score(X[120:], y[120:]) < 0.2 * reference_error_cm(np.broadcast_to(root_relative(y[:120]).mean(0),
                                                                                   pred.shape), y[120:])
    w = np.r_[np.ones(10), np.zeros(20)]
    assert est.score(X[120:], y[120:], sample_weight=w) == pytest.approx(-reference_error_cm(pred[:10], y[120:130]))


def test_predict_treats_nan_views_as_missing(data):
    X, y = data
    est = ShapeStructureModel(**SMALL).fit(X[:120], y[:120])
    Xm = X[120:].copy()
    Xm[::2, 1] = np.nan
    present = np.ones((30, 3), bool)
    present[::2, 1] = False
    np.testing.assert_array_equal(est.predict(Xm), est.infer(X[120:], present).joints)


def test_flattened_joints_fit_and_predict_in_that_shape(data):
    X, y = data
    a = ShapeStructureModel(**SMALL).fit(X[:120], y[:120])
    b = ShapeStructureModel(**SMALL).fit(X[:120], y[:120].reshape(120, 57))
    assert b.predict(X[120:]).shape == (30, 57)
    np.testing.assert_array_equal(b.predict(X[120:]).reshape(30, 19, 3), a.predict(X[120:]))
    assert a.score(X[120:], y[120:].reshape(30, 57)) == b.score(X[120:], y[120:])


def test_the_former_fit_api_is_unchanged(data):
    """Positional (contours, joints, rig) and the infer API are what silpose train and eval call."""
    X, y = data
    a = ShapeStructureModel(**SMALL).fit(X[:120], y[:120], None)
    b = ShapeStructureModel(**SMALL).fit(X=X[:120], y=y[:120])
    np.testing.assert_array_equal(a.mixture_.means_, b.mixture_.means_)


def test_unfitted_model_raises_not_fitted(data):
    X, _ = data
    with pytest.raises(NotFittedError, match="not fitted"):
        ShapeStructureModel().predict(X)
    with pytest.raises(RuntimeError, match="not fitted"):  # as before
        ShapeStructureModel().infer(X)


# ------------------------------------------------------------------ clone, GridSearchCV, cross_val_score


def test_clone_is_unfitted_with_equal_params_and_refits_identically(data):
    X, y = data
    est = ShapeStructureModel(**SMALL).fit(X[:120], y[:120])
    twin = clone(est)
    assert twin is not est and twin.get_params() == est.get_params() and not hasattr(twin, "mixture_")
    np.testing.assert_array_equal(twin.fit(X[:120], y[:120]).predict(X[120:]), est.predict(X[120:]))


def test_cross_val_score_equals_fold_by_fold_fits(data):
    X, y = data
    cv = KFold(3, shuffle=True, random_state=0)
    scores = cross_val_score(ShapeStructureModel(**SMALL), X, y, cv=cv)
    manual = [-reference_error_cm(ShapeStructureModel(**SMALL).fit(X[tr], y[tr]).predict(X[te]), y[te])
              for tr, te in cv.split(X)]
    np.testing.assert_allclose(scores, manual, rtol=1e-10)
    assert np.all(scores < 0)


def test_grid_search_picks_the_best_cross_validated_setting(data):
    X, y = data
    cv = KFold(3, shuffle=True, random_state=1)
    grid = {"n_latent": [1, 4], "structure_weight": [0.5, 2.0]}
    search = GridSearchCV(ShapeStructureModel(**SMALL), grid, cv=cv).fit(X, y)
    means = {}
    for q in grid["n_latent"]:
        for w in grid["structure_weight"]:
            est = ShapeStructureModel(**{**SMALL, "n_latent": q, "structure_weight": w})
            means[(q, w)] = cross_val_score(est, X, y, cv=cv).mean()
    best = max(means, key=means.get)
    assert (search.best_params_["n_latent"], search.best_params_["structure_weight"]) == best
    assert search.best_score_ == pytest.approx(means[best], rel=1e-10)
    refit = ShapeStructureModel(**{**SMALL, "n_latent": best[0], "structure_weight": best[1]}).fit(X, y)
    np.testing.assert_array_equal(search.predict(X[:5]), refit.predict(X[:5]))


def test_grid_search_with_the_rig_uses_the_stature_frame():
    rig = default_rig()
    config = {"name": "t", "seed": 4, "rig": rig.to_dict(), "n_points": 24}
    records = [synthetic_record(config, "train", i) for i in range(60)]
    X = np.stack([r["contours"] for r in records]).astype(np.float64)
    y = np.stack([r["joints"] for r in records]).astype(np.float64)
    est = ShapeStructureModel(n_components=1, n_latent=3, n_init=1, max_iter=20, rig=rig)
    search = GridSearchCV(est, {"structure_weight": [1.0, 10.0]}, cv=2).fit(X, y)
    assert search.best_estimator_.layout_.joint_frame == "stature" and search.best_estimator_.rig_ is not None
    assert ShapeStructureModel(n_components=1, n_latent=3, n_init=1, max_iter=5).fit(X, y).layout_.joint_frame == "metres"


# ------------------------------------------------------------------ scikit-learn's estimator checks

SKLEARN_API_CHECKS = [
    ec.check_estimator_cloneable,
    ec.check_estimator_tags_renamed,
    ec.check_valid_tag_types,
    ec.check_estimator_repr,
    ec.check_no_attributes_set_in_init,
    ec.check_parameters_default_constructible,
    ec.check_get_params_invariance,
    ec.check_set_params,
    ec.check_do_not_raise_errors_in_init_or_set_params,
    ec.check_mixin_order,
    ec.check_estimators_unfitted,
]


@pytest.mark.parametrize("check", SKLEARN_API_CHECKS, ids=lambda c: c.__name__)
def test_sklearn_api_check(check):
    check("ShapeStructureModel", ShapeStructureModel(**SMALL))


def test_sklearn_skips_the_tabular_checks_for_this_input_shape():
    from sklearn.utils import get_tags

    tags = get_tags(ShapeStructureModel())
    assert not tags.input_tags.two_d_array and tags.target_tags.required and tags.target_tags.multi_output


def test_check_fit_score_takes_y():
    for method in ("fit", "score"):
        args = list(inspect.signature(getattr(ShapeStructureModel, method)).parameters)
        assert args[1:3] == ["X", "y"], (method, args)


def test_check_estimators_fit_returns_self_and_overwrite_params(data):
    X, y = data
    est = ShapeStructureModel(**SMALL, views=(0, 2))
    before = joblib.hash(est.get_params())
    assert est.fit(X, y) is est
    assert joblib.hash(est.get_params()) == before


def test_check_dont_overwrite_parameters(data):
    X, y = data
    est = ShapeStructureModel(**SMALL)
    before = dict(vars(est))
    est.fit(X, y)
    added = [k for k in vars(est) if k not in before and not k.startswith("_") and not k.endswith("_")]
    assert added == [] and {k: vars(est)[k] for k in before} == before


def test_check_dict_unchanged_by_predict_and_score(data):
    X, y = data
    est = ShapeStructureModel(**SMALL).fit(X, y)
    before = joblib.hash({k: v for k, v in vars(est).items() if not k.startswith("_")})
    est.predict(X), est.score(X, y)
    assert joblib.hash({k: v for k, v in vars(est).items() if not k.startswith("_")}) == before


def test_check_fit_idempotent(data):
    X, y = data
    est = ShapeStructureModel(**SMALL)
    first = est.fit(X[:100], y[:100]).predict(X[100:])
    np.testing.assert_allclose(est.fit(X[:100], y[:100]).predict(X[100:]), first, rtol=1e-12, atol=1e-12)


def test_check_methods_sample_order_and_subset_invariance(data):
    X, y = data
    est = ShapeStructureModel(**SMALL).fit(X, y)
    full = est.predict(X)
    order = np.random.default_rng(0).permutation(len(X))
    np.testing.assert_allclose(est.predict(X[order]), full[order], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.concatenate([est.predict(b) for b in np.array_split(X, 7)]), full, rtol=1e-9,
                               atol=1e-12)


def test_check_estimators_nan_inf(data):
    X, y = data
    for bad_X, bad_y, what in ((X.copy(), y, "contours_px"), (X, y.copy(), "joints")):
        (bad_X if what == "contours_px" else bad_y)[3, 0, 0] = np.inf
        with pytest.raises(ValueError, match=f"{what} contains NaN or inf"):
            ShapeStructureModel(**SMALL).fit(bad_X, bad_y)


def test_check_readonly_memmap_input(data, tmp_path):
    X, y = data
    np.save(tmp_path / "X.npy", X), np.save(tmp_path / "y.npy", y)
    Xm, ym = np.load(tmp_path / "X.npy", mmap_mode="r"), np.load(tmp_path / "y.npy", mmap_mode="r")
    est = ShapeStructureModel(**SMALL).fit(Xm, ym)
    np.testing.assert_array_equal(est.predict(Xm), ShapeStructureModel(**SMALL).fit(X, y).predict(X))
    assert np.isfinite(est.score(Xm, ym))
