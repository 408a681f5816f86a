"""InferenceResult.merge: the frames of each part go to their indices, whatever the parts' order and shape of
index sets; a field a part lacks is filled there (NaN, or the field's fill value)."""

from __future__ import annotations

import numpy as np

from silpose.model.result import InferenceResult


def _part(rng, n: int, robust: bool) -> InferenceResult:
    res = InferenceResult.nan(n, views=(0, 1), n_points=5, n_components=3, robust=robust)
    for name in ("joints", "contours_px", "responsibilities", "log_marginal"):
        getattr(res, name)[:] = rng.normal(size=getattr(res, name).shape)
    res.views_present[:] = rng.random(res.views_present.shape) < 0.5
    if robust:
        res.robust_weights[:] = rng.random(res.robust_weights.shape)
        res.robust_input_px[:] = rng.normal(size=res.robust_input_px.shape)
    return res


def _expected(parts, order, n, name, fill):
    """The merged field by hand: one frame at a time."""
    first = next(getattr(p, name) for p in parts if getattr(p, name) is not None)
    out = np.full((n,) + first.shape[1:], fill, dtype=first.dtype)
    for p, idx in zip(parts, order):
        if getattr(p, name) is not None:
            for j, i in enumerate(idx):
                out[i] = getattr(p, name)[j]
    return out


def test_merge_puts_each_frame_at_its_index():
    rng = np.random.default_rng(0)
    n = 11
    for order in ([np.arange(0, 4), np.arange(4, 9), np.arange(9, 11)],  # contiguous blocks
                  [np.array([3, 0, 7, 10]), np.array([1, 2, 4, 5, 6]), np.array([9, 8])]):  # scattered
        parts = [_part(rng, len(o), robust=True) for o in order]
        got = InferenceResult.merge(parts, order, n)
        for name in ("joints", "contours_px", "responsibilities", "log_marginal", "views_present", "robust_weights"):
            np.testing.assert_array_equal(getattr(got, name), _expected(parts, order, n, name, np.nan), err_msg=name)


def test_merge_fills_a_field_some_parts_lack():
    rng = np.random.default_rng(1)
    order = [np.arange(0, 3), np.arange(3, 7)]
    parts = [_part(rng, 3, robust=True), _part(rng, 4, robust=False)]  # the second has no robust fields
    got = InferenceResult.merge(parts, order, 7)
    np.testing.assert_array_equal(got.robust_weights, _expected(parts, order, 7, "robust_weights", 0.0))
    assert np.all(got.robust_weights[3:] == 0.0)  # robust_weights' own fill value
    assert np.all(np.isnan(got.robust_input_px[3:])) and not np.isnan(got.robust_input_px[:3]).any()
    assert not got.excursions_trimmed[3:].any()
