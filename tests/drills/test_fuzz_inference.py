"""Fuzz: bad inputs to ``ShapeStructureModel.infer`` and the conditional (``condition``, ``condition_rows``).

NaN, infinities, huge values, wrong shapes and dtypes, all views missing, unknown or repeated
views, bad noise variances. Each call raises the documented ``ValueError`` or returns a finite
answer (joints, their spread, responsibilities, log marginal, normalised reconstructions).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import array_shapes, arrays

from silpose.model.conditioning import condition, condition_rows
from silpose.app.training import fit_dataset
from silpose.model.shape_model import ShapeStructureModel
from silpose.shared.dataset import load_split

FUZZ = settings(max_examples=80, deadline=3000, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
ODD = [np.nan, np.inf, -np.inf, 1e300, -1e300, 1e15, -1e15, 1e-300, 0.0, -0.0]


@pytest.fixture(scope="module")
def fitted(clean_dataset):
    root, _ = clean_dataset
    train, test = load_split(root, "train"), load_split(root, "test")
    model = fit_dataset(ShapeStructureModel(2, 3, n_init=1, max_iter=10), train)
    return model, test.contours.astype(np.float64)


def check_result(r, n: int, k: int) -> None:
    assert r.joints.shape == (n, 19, 3)
    for name in ("joints", "joints_best", "joint_std", "responsibilities", "log_marginal", "contours_norm"):
        assert np.all(np.isfinite(getattr(r, name))), name
    np.testing.assert_allclose(r.responsibilities.sum(1), 1.0, rtol=1e-9)
    # present views are reconstructed in pixels with their own (finite) normalisation
    present_px = r.contours_px[r.views_present]
    assert np.all(np.isfinite(present_px)), "present view mapped to non-finite pixels"


def infer_or_value_error(model, *args, **kwargs):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", np.ComplexWarning)  # a silently dropped imaginary part is a failure
            return model.infer(*args, **kwargs)
    except ValueError as exc:
        assert str(exc), "empty error message"
        return None


@FUZZ
@given(data=st.data())
def test_odd_values_and_missing_views(fitted, data):
    model, contours = fitted
    c = contours.copy()
    n, k = c.shape[:2]
    for _ in range(data.draw(st.integers(0, 4))):
        idx = tuple(data.draw(st.integers(0, s - 1)) for s in c.shape)
        c[idx] = data.draw(st.sampled_from(ODD))
    if data.draw(st.booleans()):  # a whole view of one frame replaced by one odd value
        c[data.draw(st.integers(0, n - 1)), data.draw(st.integers(0, k - 1))] = data.draw(st.sampled_from(ODD))
    present = data.draw(st.one_of(st.none(), arrays(np.bool_, (n, k))))
    s2 = data.draw(st.one_of(st.none(), st.sampled_from([0.0, 1e-12, 0.03, 1e6, -1.0, np.nan, np.inf])))
    r = infer_or_value_error(model, c, present, s2)
    if r is not None:
        check_result(r, n, k)


@FUZZ
@given(shape=array_shapes(min_dims=0, max_dims=5, min_side=0, max_side=5),
       input_views=st.one_of(st.none(), st.lists(st.integers(-2, 6), max_size=5)))
def test_wrong_shapes_and_views(fitted, shape, input_views):
    model, contours = fitted
    c = np.resize(contours, shape) if np.prod(shape) else np.zeros(shape)
    r = infer_or_value_error(model, c, input_views=input_views)
    if r is not None:
        check_result(r, c.shape[0], c.shape[1])


@FUZZ
@given(n_views=st.integers(1, 4), data=st.data())
def test_view_subsets_in_rig_order(fitted, n_views, data):
    model, contours = fitted
    views = data.draw(st.lists(st.integers(0, 3), min_size=n_views, max_size=n_views, unique=True))
    present = data.draw(arrays(np.bool_, (contours.shape[0], n_views)))
    r = infer_or_value_error(model, contours[:, views], present, input_views=views)
    if r is None:
        assert (~present).all(axis=1).any()  # the only error here: a frame with every view missing
    else:
        check_result(r, contours.shape[0], 4)
        assert np.array_equal(r.views_present[:, views], present)


@pytest.mark.parametrize("make", [
    lambda c: c.astype(np.float32),
    lambda c: c.astype(np.float16),
    lambda c: np.round(c).astype(np.int64),
    lambda c: c.astype(np.int16),
    lambda c: c > 100,
    lambda c: c.astype(object),
    lambda c: c.astype(str),
    lambda c: np.where(np.indices(c.shape)[0] == 0, None, c.astype(object)),
    lambda c: c.astype(np.complex128) + 1j,
    lambda c: c.tolist(),
    lambda c: np.asfortranarray(c),
    lambda c: c[:, ::-1],
], ids=["float32", "float16", "int64", "int16", "bool", "object", "str", "object_none", "complex", "list",
        "fortran", "reversed_views"])
def test_dtypes(fitted, make):
    model, contours = fitted
    c = make(contours)
    r = infer_or_value_error(model, c)
    if r is not None:
        check_result(r, contours.shape[0], 4)


def test_same_answer_for_float32_and_lists(fitted):
    model, contours = fitted
    a = model.infer(contours)
    np.testing.assert_allclose(model.infer(contours.tolist()).joints, a.joints)
    np.testing.assert_allclose(model.infer(contours.astype(np.float32)).joints, a.joints, atol=1e-4)


# ------------------------------------------------------------------ the conditional itself


@FUZZ
@given(data=st.data())
def test_condition_and_condition_rows(fitted, data):
    model, _ = fitted
    mix = model.mixture_
    d = mix.means_.shape[1]
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(0, 4))
    X = mix.means_[rng.integers(0, mix.means_.shape[0], max(n, 1))][:n] + rng.normal(0, 0.01, (n, d))
    for _ in range(data.draw(st.integers(0, 3))):
        if n:
            X[data.draw(st.integers(0, n - 1)), data.draw(st.integers(0, d - 1))] = data.draw(st.sampled_from(ODD))
    noise = data.draw(st.sampled_from([0.0, 0.03, -1.0, np.nan, np.inf, 1e300]))
    kind = data.draw(st.sampled_from(["index", "mask", "bad_index"]))
    if kind == "index":
        obs = np.sort(rng.choice(d, size=data.draw(st.integers(0, 50)), replace=False))
    elif kind == "mask":
        obs = rng.random(d) < data.draw(st.floats(0, 1))
    else:
        obs = np.asarray(data.draw(st.lists(st.integers(-5, d + 5), max_size=5)))
    x_obs = X[:, obs] if kind != "bad_index" else X[:, :len(obs)]
    try:
        r = condition(mix, x_obs, obs, noise)
    except ValueError:
        pass
    else:
        for name in ("mean", "best_mean", "responsibilities", "variance", "log_marginal"):
            assert np.all(np.isfinite(getattr(r, name))), name
    # condition_rows: NaN marks missing dims
    Xr = X.copy()
    if n:
        Xr[:, rng.random(d) < 0.5] = np.nan
    try:
        r = condition_rows(mix, Xr, noise)
    except ValueError:
        pass
    else:
        for name in ("mean", "best_mean", "responsibilities", "variance"):
            assert np.all(np.isfinite(getattr(r, name))), name
