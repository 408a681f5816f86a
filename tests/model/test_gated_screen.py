"""The per-frame component sets of inference (``silpose.model.gated``) and the float32 screen that chooses them
(``silpose.model.screen``), each against the straightforward float64 conditioning over every component.

- ``condition_gated`` with a row's set holding every component equals ``Conditioner.__call__`` without gating; with
  each row's set cut to its non-negligible components, it equals it to ~1e-9;
- the screen's float32 log densities agree with the exact ones to well within ``SCREEN_MARGIN``, and its
  candidates hold every component within ``GATE_NATS`` of a row's best;
- ``Posterior.infer`` with a screen equals it without one, at two noise levels sharing the screen;
- ``median_last`` is ``np.median`` bit for bit.
"""

import warnings

import numpy as np
import pytest

import silpose.model.conditioning as conditioning
from silpose.model.checks import model_inputs
from silpose.model.conditioning import Conditioner, MixtureParams
from silpose.model.gated import condition_gated
from silpose.model.robust import median as median_module
from silpose.model.robust.median import median_last
from silpose.model.screen import SCREEN_MARGIN, Screen, ScreenMatrices
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes

FIELDS = ("reconstruction", "best_mean", "variance", "responsibilities", "log_marginal")


def _mixture(rng, m=6, d=16, q=3, spread=3.0):
    means = rng.normal(size=(m, d)) * spread
    return MixtureParams(rng.dirichlet(np.full(m, 2.0)), means, rng.normal(size=(m, d, q)), rng.uniform(0.1, 0.4, m))


def _ungated(monkeypatch, p, obs, noise, X):
    monkeypatch.setattr(conditioning, "GATE_NATS", np.inf)
    full = Conditioner(p, obs, noise, detail=np.arange(12, 16), reconstruct=True)(X)
    monkeypatch.undo()
    return full


@pytest.mark.parametrize("noise", [0.2, "per_dim"])
def test_gated_conditioning_equals_the_full_one(noise, monkeypatch):
    rng = np.random.default_rng(0)
    p = _mixture(rng, spread=1.0)  # components overlap: every row weighs several
    obs = np.arange(11)
    noise = rng.uniform(0.0, 0.5, obs.size) if noise == "per_dim" else noise
    X = p.means_[rng.integers(6, size=9)][:, obs] + rng.normal(size=(9, obs.size))
    full = _ungated(monkeypatch, p, obs, noise, X)
    cond = Conditioner(p, obs, noise, detail=np.arange(12, 16), reconstruct=True)
    every = condition_gated(cond, X, np.ones((9, 6), dtype=bool))
    for key in FIELDS:
        np.testing.assert_allclose(getattr(every, key), getattr(full, key), rtol=1e-10, atol=1e-12, err_msg=key)
    with pytest.raises(ValueError, match="at least one component"):
        condition_gated(cond, X, np.zeros((9, 6), dtype=bool))
    with pytest.raises(ValueError, match="shape"):
        condition_gated(cond, X, np.ones((9, 5), dtype=bool))


def test_gated_conditioning_with_each_rows_own_components(monkeypatch):
    rng = np.random.default_rng(1)
    p = _mixture(rng, spread=20.0)  # far apart: a row has one or two non-negligible components
    obs = np.arange(11)
    X = p.means_[[0, 0, 3, 5, 2]][:, obs] + rng.normal(size=(5, obs.size))
    X[4] = 0.5 * (p.means_[1, obs] + p.means_[2, obs])  # between two components
    full = _ungated(monkeypatch, p, obs, 0.2, X)
    mask = full.responsibilities > np.exp(-30.0)
    mask[1] = True  # one row with every component
    assert mask.sum(axis=1).min() == 1 and mask.sum() < mask.size
    got = condition_gated(Conditioner(p, obs, 0.2, detail=np.arange(12, 16), reconstruct=True), X, mask)
    for key in ("reconstruction", "best_mean", "variance"):
        np.testing.assert_allclose(getattr(got, key), getattr(full, key), rtol=1e-9, atol=1e-10, err_msg=key)
    np.testing.assert_allclose(got.log_marginal, full.log_marginal, rtol=1e-12)
    np.testing.assert_allclose(got.responsibilities[mask], full.responsibilities[mask], rtol=1e-9)
    assert np.all(got.responsibilities[~mask] == 0)


def test_screen_log_densities_and_candidates():
    rng = np.random.default_rng(2)
    p = _mixture(rng, m=8, d=40, q=5, spread=0.7)
    obs = np.arange(32)
    X = p.means_[rng.integers(8, size=30)][:, obs] + 0.5 * rng.normal(size=(30, obs.size))
    sc = Screen(ScreenMatrices(p.components_, p.means_, obs), X)
    for s2 in (0.01, 0.3):
        cond = Conditioner(p, obs, s2)
        full = cond(X)
        with np.errstate(divide="ignore"):
            exact = np.log(full.responsibilities) + full.log_marginal[:, None]  # log pi_i N(a; ...) per component
        cand = sc.candidates(cond)
        near = exact >= exact.max(axis=1, keepdims=True) - conditioning.GATE_NATS
        assert np.all(cand[near]) and not cand.all()
        # the screened log densities: reconstructed from the candidates' own gate
        u = sc.z.astype(np.float64) - sc.mats.w_mu
        quad = np.einsum("nmq,mqr,nmr->nm", u, cond.Kinv, u) * cond.invD ** 2
        approx = cond.log_norm - 0.5 * ((sc.xx[:, None] - 2 * sc.xm + cond.mu_sq) * cond.invD - quad)
        finite = np.isfinite(exact)
        assert np.abs(approx - exact)[finite].max() < 1e-3 * SCREEN_MARGIN


@pytest.fixture(scope="module")
def small_model():
    data = make_linear_shapes(200, n_views=3, n_points=24, seed=4, n_clusters=5)
    model = ShapeStructureModel(8, 3, n_init=1, max_iter=8, noise_variance=1e-3, random_state=0,
                                joint_frame="metres").fit(data.contours[:150], data.joints[:150])
    return model, data.contours[150:].astype(np.float64)


def test_screened_posterior_equals_the_full_one(small_model, monkeypatch):
    model, contours = small_model
    present = np.ones(contours.shape[:2], dtype=bool)
    present[::4, 1] = False  # two view patterns
    inputs = model_inputs(model.layout_, model.n_rig_views_, contours, present, None, None, None)
    post = model.posterior()
    screen: dict = {}
    s2_rows = np.where(np.arange(len(contours)) % 3 == 0, 1e-3, 1e-2)
    monkeypatch.setattr(conditioning, "GATE_NATS", np.inf)
    for s2 in (1e-3, s2_rows):  # the second call reuses the screen made by the first
        got, _ = post.infer(inputs, s2, screen=screen)
        ref, _ = post.infer(inputs, s2)
        np.testing.assert_allclose(got.joints, ref.joints, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(got.contours_px, ref.contours_px, rtol=1e-9)
        np.testing.assert_allclose(got.log_marginal, ref.log_marginal, rtol=1e-12)
        assert (got.responsibilities == 0).any()  # the screen left components out
    assert len(screen) == 2


@pytest.mark.parametrize("simd_sort", [True, False])
def test_median_last_is_numpys_median(simd_sort, monkeypatch):
    """Both paths (a sort where it is vectorised, else a partition at the middle) give np.median bit for bit."""
    monkeypatch.setattr(median_module, "SORT_IS_SIMD", simd_sort)
    rng = np.random.default_rng(3)
    for shape in [(6, 4, 200), (3, 201), (5, 1), (4, 2), (1000, 10), (2, 0)]:
        v = rng.exponential(size=shape)
        if v.size:
            v[0, ..., 0] = np.nan
            v[-1] = np.round(v[-1], 1)  # ties
            v[1, ..., -1] = -np.inf
        with warnings.catch_warnings():  # np.median of an empty row warns ("Mean of empty slice") and gives NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            want = np.median(v, axis=-1)
        np.testing.assert_array_equal(median_last(v), want)


def test_gated_rows_read_as_slices_and_single_components_equal_each_rows_own_conditioning():
    """Runs of consecutive rows with one component (read as slices, written as mu_i + x_hat W_i^T) and scattered
    rows with one or several, against each row conditioned on its own component set (``Conditioner.__call__``)."""
    rng = np.random.default_rng(7)
    p = _mixture(rng, spread=20.0)
    obs = np.arange(11)
    which = [0, 0, 0, 3, 3, 5, 0, 2, 2, 1]
    X = p.means_[which][:, obs] + rng.normal(size=(len(which), obs.size))
    mask = np.zeros((len(which), 6), dtype=bool)
    mask[np.arange(len(which)), which] = True
    mask[6, [0, 4]] = True  # a row with two components amid component 0's rows
    mask[9] = True  # a row with every component
    for noise in (0.2, rng.uniform(0.0, 0.5, obs.size)):
        cond = Conditioner(p, obs, noise, detail=np.arange(12, 16), reconstruct=True)
        got = condition_gated(cond, X, mask)
        for r in range(len(which)):
            want = cond(X[r:r + 1], components=np.flatnonzero(mask[r]))
            for key in ("reconstruction", "best_mean", "variance", "responsibilities"):
                np.testing.assert_allclose(getattr(got, key)[r], getattr(want, key)[0], rtol=1e-9, atol=1e-10,
                                           err_msg=f"{key} row {r}")
            np.testing.assert_allclose(got.log_marginal[r], want.log_marginal[0], rtol=1e-12)
        single = mask.sum(axis=1) == 1
        assert np.all(got.responsibilities[single][mask[single]] == 1.0)
