"""The compiled loops of robust inference (``silpose.model.robust.kernels``) give numpy's answers bit for bit.

References: ``np.median`` for the selection; the numpy composition of ``point_weights`` (Tukey's weights of the
index-correspondence distances) and ``pseudo_observation`` for the reweighting pass's kernel, on views with ties,
zero residuals, NaN points and absent views; and the reweighting pass itself with the kernel against the same pass
with the numpy steps (``window`` 0 routes through the kernel; the numpy steps are what a window of 0 means).
"""

from __future__ import annotations

import numpy as np
import pytest

from silpose.model.robust import RobustSettings, point_weights
from silpose.model.robust.kernels import biweight_pseudo, median_of
from silpose.model.robust.loop import pseudo_observation, reweighted_observation


@pytest.mark.parametrize("n", [1, 2, 3, 7, 200, 201])
def test_median_of_is_numpys_median(n):
    rng = np.random.default_rng(n)
    for trial in range(200):
        v = rng.normal(size=n)
        if trial % 3 == 0:
            v = np.round(v * 2)  # many ties
        if trial % 7 == 0:
            v[:] = 0.5  # all equal
        want = np.median(v)
        got = median_of(v.copy())
        assert got == want or (np.isnan(got) and np.isnan(want))
    v = rng.normal(size=n)
    v[n // 2] = np.nan
    assert np.isnan(median_of(v))


def _numpy_pass(observed, rec, present, threshold, floor):
    dx, dy = observed[..., 0] - rec[..., 0], observed[..., 1] - rec[..., 1]
    w = point_weights(np.sqrt(dx * dx + dy * dy), threshold, floor)
    u = np.where(present[..., None], w, 0.0)
    pseudo = np.where(present[..., None, None], pseudo_observation(rec, observed, u), observed)
    return u, pseudo


def test_biweight_pseudo_is_the_numpy_composition():
    rng = np.random.default_rng(3)
    f, k, n = 40, 4, 60
    rec = rng.normal(100, 20, size=(f, k, n, 2))
    observed = rec + rng.standard_t(2, size=rec.shape)  # heavy tails: many zero weights
    observed[0, 0] = rec[0, 0]  # zero residuals: median 0, scale the floor
    observed[1, 1] = np.round(observed[1, 1])
    rec[1, 1] = np.round(rec[1, 1])  # ties
    observed[2, 2, 5, 0] = np.nan  # a NaN point: its whole view gets weight 0
    present = rng.random((f, k)) > 0.2
    present[2, 2] = True
    for threshold, floor in ((2.0, 0.0), (4.5, 1.0), (3.0, 0.3)):  # the defaults last (the checks after the loop)
        want_u, want_p = _numpy_pass(observed, rec, present, threshold, floor)
        got_u, got_p = biweight_pseudo(observed, rec, present, threshold, floor)
        assert np.array_equal(got_u, want_u)
        assert np.array_equal(got_p, want_p, equal_nan=True)
    assert (got_u[2, 2] == 0).all() and (got_u[0, 0] > 0).all() and (got_u[~present] == 0).all()
    assert 0.01 < (got_u[present] == 0).mean() < 0.5  # the heavy tails were rejected, the rest kept


def test_reweighting_pass_kernel_equals_the_numpy_steps(monkeypatch):
    rng = np.random.default_rng(4)
    rec = rng.normal(100, 20, size=(300, 4, 50, 2))
    observed = rec + rng.normal(0, 2, size=rec.shape)
    present = rng.random((300, 4)) > 0.1
    s = RobustSettings()
    got_u, got_p = reweighted_observation(observed, rec, present, s)
    want_u, want_p = _numpy_pass(observed, rec, present, s.threshold, s.scale_floor_px)
    assert np.array_equal(got_u, want_u) and np.array_equal(got_p, want_p)
