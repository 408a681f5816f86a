"""The shortcuts of inference at many components and many passes, each against the straightforward computation.

- components more than 30 nats (``GATE_NATS``) below a frame's best are left out of the output product and of
  robust inference's reweighting passes: the answer equals the ungated one to ~1e-9 relative;
- a component subset (``Conditioner(...)(X, components=...)``) equals the full conditioning when the others
  are negligible;
- robust passes stop for frames whose reconstruction settled (``SETTLED_PX``): within that tolerance of all
  passes;
- the batched slide fit of re-indexing equals the per-view least squares (``fit_slide``).
"""

import numpy as np
import pytest

import silpose.model.conditioning as conditioning
import silpose.model.robust.loop as loop
from silpose.model.conditioning import Conditioner, MixtureParams
from silpose.model.robust.reindex import fit_slide, fit_slides
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes


def _far_apart_mixture(rng, m=6, d=14, q=3):
    """A mixture whose components sit far apart: each observation has one or two non-negligible components."""
    means = rng.normal(size=(m, d)) * 20.0
    return MixtureParams(np.full(m, 1.0 / m), means, rng.normal(size=(m, d, q)), np.full(m, 0.2)), means


def test_output_gating_and_component_subsets_equal_the_full_conditioning(monkeypatch):
    rng = np.random.default_rng(0)
    p, means = _far_apart_mixture(rng)
    obs = np.arange(10)
    X = means[[0, 0, 3, 5]][:, obs] + rng.normal(size=(4, 10))
    gated = Conditioner(p, obs, 0.1, reconstruct=True)(X, return_components=True)
    monkeypatch.setattr(conditioning, "GATE_NATS", np.inf)
    full = Conditioner(p, obs, 0.1, reconstruct=True)(X, return_components=True)
    assert gated.responsibilities.max(axis=1).min() > 1 - 1e-12  # the others are far below the gate
    np.testing.assert_allclose(gated.reconstruction, full.reconstruction, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(gated.variance, full.variance, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(gated.responsibilities, full.responsibilities)
    np.testing.assert_array_equal(gated.component_means, full.component_means)  # still every component's
    sub = Conditioner(p, obs, 0.1, reconstruct=True)(X[:2], components=[0, 2], return_components=True)
    np.testing.assert_allclose(sub.reconstruction, full.reconstruction[:2], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(sub.log_marginal, full.log_marginal[:2], rtol=1e-12)
    np.testing.assert_allclose(sub.responsibilities[:, [0, 2]], full.responsibilities[:2, [0, 2]], rtol=1e-9, atol=1e-300)
    assert np.all(sub.responsibilities[:, [1, 3, 4, 5]] == 0) and np.isnan(sub.component_means[:, 1]).all()
    with pytest.raises(ValueError, match="components"):
        Conditioner(p, obs, 0.1)(X, components=[0, 0])


@pytest.fixture(scope="module")
def many_component_model():
    data = make_linear_shapes(400, n_views=3, n_points=24, seed=4, n_clusters=6)
    model = ShapeStructureModel(12, 3, n_init=1, max_iter=20, noise_variance=1e-3, random_state=0,
                                joint_frame="metres").fit(data.contours[:300], data.joints[:300])
    contours = data.contours[300:].astype(np.float64)
    rng = np.random.default_rng(1)
    contours[::3, 0, 5:9] += rng.normal(0, 6.0, size=contours[::3, 0, 5:9].shape)  # outliers for the weights
    return model, contours


def test_gated_robust_inference_equals_the_ungated(many_component_model, monkeypatch):
    model, contours = many_component_model
    gated = model.infer(contours, robust=True)
    assert (gated.responsibilities < loop.GATE_WEIGHT).any()  # some components are gated
    monkeypatch.setattr(loop, "GATE_WEIGHT", -1.0)
    monkeypatch.setattr(conditioning, "GATE_NATS", np.inf)
    model._posterior = None
    full = model.infer(contours, robust=True)
    scale = np.abs(full.joints).max()
    np.testing.assert_allclose(gated.joints, full.joints, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(gated.contours_px, full.contours_px, rtol=1e-9)
    np.testing.assert_array_equal(gated.excursions_trimmed, full.excursions_trimmed)


def test_settled_frames_stop_within_the_tolerance_of_every_pass(many_component_model, monkeypatch):
    model, contours = many_component_model
    settled = model.infer(contours, robust=True, hypotheses=2)
    tol = loop.SETTLED_PX
    monkeypatch.setattr(loop, "SETTLED_PX", 0.0)
    every = model.infer(contours, robust=True, hypotheses=2)
    # a frame stops when a pass moved it < SETTLED_PX; the passes it skipped move it less (they converge)
    assert np.abs(settled.contours_px - every.contours_px).max() < 5 * tol
    size = np.abs(every.joints).max()
    # the joints move with the contours: by at most a few % of the tolerance (px) per unit of joint size
    assert np.abs(settled.joints - every.joints).max() < 0.05 * tol * size
    np.testing.assert_array_equal(settled.hypotheses.component, every.hypotheses.component)


def test_batched_slide_fit_equals_the_per_view_least_squares():
    rng = np.random.default_rng(0)
    v, n = 60, 200
    t = 2 * np.pi * np.arange(n) / n
    offsets = np.round(rng.normal(0, 2, (v, 1)) + 3 * np.sin(t)[None] * rng.normal(size=(v, 1))
                       + rng.normal(0, 1, (v, n))).astype(int)
    distances = np.abs(rng.normal(0, 3, (v, n)))
    distances[:3] = 1e3  # too little weight: no slide
    sigma = rng.uniform(2, 4, v)
    slides, chi2 = fit_slides(offsets, distances, sigma, 3, 0.2236)
    for j in range(v):
        s1, c1 = fit_slide(offsets[j], distances[j], sigma[j], 3, 0.2236)
        np.testing.assert_allclose(slides[j], s1, rtol=1e-9, atol=1e-9)
        assert chi2[j] == pytest.approx(c1, rel=1e-9, abs=1e-12)
    assert np.all(slides[:3] == 0) and np.all(chi2[:3] == 0)
