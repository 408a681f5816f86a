"""Robust inference: Tukey weights, correspondences, the pseudo-observation iteration and its use in infer.

Independent reference for the iteration: conditioning with per-dimension noise variances ``D / u``
(the Conditioner's vector-noise path, itself checked against dense conditioning in
test_conditional.py) -- the fixed point the module docstring claims.
"""

import numpy as np
import pytest

from silpose.model.conditioning import Conditioner, MixtureParams
from silpose.model.robust import NOISE_LEVELS, RobustSettings, frame_noise_variance, point_weights, snap_correspondences
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.shared.skeleton import root_relative


def test_tukey_weights_by_hand():
    r = np.array([0.0, 1.0, 1.0, 1.0, 2.0, 100.0])
    u = point_weights(r, threshold=3.0, scale_floor_px=0.0)
    s = 1.4826 * 1.0  # the median is 1
    z = r / (3.0 * s)
    expected = np.where(z < 1, (1 - z**2) ** 2, 0.0)
    np.testing.assert_allclose(u, expected)
    assert u[0] == 1.0 and u[-1] == 0.0
    assert point_weights(np.array([np.nan, 1.0, 1.0]))[0] == 0.0
    with pytest.raises(ValueError, match="iterations"):
        RobustSettings(iterations=0)


def test_snap_finds_a_shifted_correspondence():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    circle = np.stack([np.cos(t), np.sin(t)], -1) * 20
    shifted = np.roll(circle, 2, axis=0)  # the same points, indices moved by 2
    matched, dist = snap_correspondences(shifted, circle, window=3)
    np.testing.assert_allclose(matched, circle, atol=1e-12)
    np.testing.assert_allclose(dist, 0.0, atol=1e-12)
    same, d0 = snap_correspondences(shifted, circle, window=0)
    assert np.array_equal(same, shifted) and d0.min() > 1.0


def test_pseudo_observation_fixed_point_is_weighted_conditioning():
    rng = np.random.default_rng(0)
    d, q, d_a = 12, 3, 8
    p = MixtureParams(np.ones(1), rng.normal(size=(1, d)), rng.normal(size=(1, d, q)), np.array([0.05]))
    obs = np.arange(d_a)
    a = rng.normal(size=d_a) * 2
    u = rng.uniform(0.2, 1.0, size=d_a)
    s2 = 0.1
    D = p.noise_variance_[0] + s2
    weighted = Conditioner(p, obs, D / u - p.noise_variance_[0], reconstruct=True)(a)  # noise D / u per dim
    plain = Conditioner(p, obs, s2, reconstruct=True)
    x = a.copy()
    for _ in range(2000):
        rec = plain(x).reconstruction[0, :d_a]
        x = rec + u * (a - rec)
    np.testing.assert_allclose(plain(x).reconstruction, weighted.reconstruction, atol=1e-8)


@pytest.fixture(scope="module")
def fitted():
    train = make_linear_shapes(400, n_views=3, n_points=24, seed=11)
    test = make_linear_shapes(460, n_views=3, n_points=24, seed=11)
    model = ShapeStructureModel(n_components=2, n_latent=6, structure_weight=2.0, noise_variance=1e-3, n_init=1,
                                random_state=0, joint_frame="metres").fit(train.contours, train.joints)
    return model, test.contours[400:].astype(np.float64), test.joints[400:]


def _err(pred, truth):
    return 100 * np.linalg.norm(pred - root_relative(truth.astype(np.float64)), axis=-1).mean()


def test_robust_inference_ignores_an_outlying_stretch(fitted):
    model, contours, joints = fitted
    bad = contours.copy()
    bad[:, 1, 3:8] += np.array([25.0, -15.0])  # 5 of 24 points of view 1 thrown ~30 px away (a blob)
    gauss = model.infer(bad)
    # the weights alone: these random linear "contours" are not outlines, so excursion trimming (which
    # reads outline geometry, test_excursions.py) is off here
    rob = model.infer(bad, robust=RobustSettings(excursion_passes=0))
    clean = model.infer(contours)
    assert _err(rob.joints, joints) < 0.5 * _err(gauss.joints, joints)
    assert _err(rob.joints, joints) < 2.0 * _err(clean.joints, joints) + 0.5
    # the outlying points get (near) zero weight, the others weight near 1
    assert rob.robust_weights[:, 1, 3:8].mean() < 0.1 and rob.robust_weights[:, 0].mean() > 0.8
    # the observed input's density (robust inference's Gaussian pass conditions the components a float32 screen
    # keeps, silpose.model.screen: equal to rounding)
    np.testing.assert_allclose(rob.log_marginal, gauss.log_marginal, rtol=1e-10)
    assert np.all(rob.log_marginal_robust > rob.log_marginal)
    # on clean input robust inference changes little
    assert abs(_err(model.infer(contours, robust=True).joints, joints) - _err(clean.joints, joints)) < 0.5


def test_robust_inference_with_a_missing_view(fitted):
    model, contours, joints = fitted
    present = np.ones((len(contours), 3), bool)
    present[:, 2] = False
    c = contours.copy()
    c[:, 2] = np.nan
    res = model.infer(c, present, robust=RobustSettings(iterations=3, window=2))
    assert np.all(res.robust_weights[:, 2] == 0) and np.isfinite(res.joints).all()


def test_frame_noise_variance_follows_the_residual_scale():
    rng = np.random.default_rng(1)
    rec = rng.normal(size=(3, 2, 50, 2))
    sigma = np.array([0.001, 0.05, 0.3])  # per coordinate, normalised units
    obs = rec + rng.normal(size=rec.shape) * sigma[:, None, None, None]
    present = np.ones((3, 2), bool)
    s2 = frame_noise_variance(obs, rec, present, 0.01, noise_scale=10.0)
    assert s2[0] == 0.01  # never below the model's s^2
    assert list(s2) == sorted(s2) and set(s2) <= set(0.01 * NOISE_LEVELS)
    # the level nearest (log scale) to 10 sigma^2, sigma estimated from the median residual
    for i in (1, 2):
        r = np.linalg.norm(obs[i] - rec[i], axis=-1)
        want = 10 * (1.4826 * np.median(r)) ** 2 / 2
        assert s2[i] == (0.01 * NOISE_LEVELS)[np.argmin(np.abs(np.log(0.01 * NOISE_LEVELS) - np.log(want)))]
    # an absent view does not count
    obs[2, 1] = rec[2, 1] + 100.0
    present[2, 1] = False
    assert frame_noise_variance(obs, rec, present, 0.01)[2] == s2[2]


def test_adaptive_noise_is_reported_and_can_be_switched_off(fitted):
    model, contours, _ = fitted
    bad = contours.copy()
    bad[:10] += np.random.default_rng(0).normal(0, 4.0, size=bad[:10].shape)  # heavy jitter on 10 frames
    res = model.infer(bad, robust=True)
    assert res.noise_variance.shape == (len(bad),) and np.all(res.noise_variance >= model.noise_variance)
    assert res.noise_variance[:10].min() > np.median(res.noise_variance[10:])
    fixed = model.infer(bad, robust=RobustSettings(noise_scale=None))
    assert fixed.noise_variance is None
