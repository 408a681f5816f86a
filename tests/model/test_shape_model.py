"""ShapeStructureModel on synthetic data with a known linear contour <- joints link.

References: the trivial mean-pose baseline, and dense Gaussian conditioning (full d x d
covariances, scipy's multivariate normal: the ``dense_reference`` fixture of tests/model/conftest.py)
for the marginalisation of missing views.
"""

import numpy as np
import pytest

from silpose.model.conditioning import Conditioner
from silpose.model.features import denormalise_contours, normalise_contours
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.shared.contours import normalise
from silpose.shared.skeleton import root_relative

N_POINTS = 16


@pytest.fixture(scope="module")
def fitted():
    train = make_linear_shapes(400, n_views=3, n_points=N_POINTS, seed=3)
    # same fixed structure (seed), new samples: the last 80 of a longer draw
    test = make_linear_shapes(480, n_views=3, n_points=N_POINTS, seed=3)
    test.contours, test.joints = test.contours[400:], test.joints[400:]
    test.centroid, test.scale = test.centroid[400:], test.scale[400:]
    model = ShapeStructureModel(
        n_components=2, n_latent=6, structure_weight=2.0, noise_variance=1e-4, n_init=2, random_state=0
    ).fit(train.contours, train.joints)
    return model, train, test


def _err_cm(pred, joints):
    return 100 * np.linalg.norm(pred - root_relative(joints.astype(np.float64)), axis=-1).mean()


def test_infers_joints_and_beats_mean_pose(fitted):
    model, train, test = fitted
    res = model.infer(test.contours)
    err = _err_cm(res.joints, test.joints)
    baseline = _err_cm(np.broadcast_to(root_relative(train.joints).mean(0), res.joints.shape), test.joints)
    assert err < 0.2 * baseline, (err, baseline)
    assert _err_cm(res.joints_best, test.joints) < 0.3 * baseline
    assert res.joints.shape == res.joint_std.shape == (80, 19, 3)
    assert res.contours_norm.shape == res.contours_px.shape == (80, 3, N_POINTS, 2)
    np.testing.assert_allclose(res.responsibilities.sum(1), 1.0, atol=1e-10)
    assert np.all(res.joint_std >= 0) and np.all(np.isfinite(res.log_marginal))
    # observed views are reconstructed close to their input (pixel noise 0.3 px, sizes 40-60 px)
    assert np.abs(res.contours_px - test.contours).mean() < 1.0


def test_missing_view_is_marginalised_exactly(fitted, dense_reference):
    model, _, test = fitted
    lay = model.layout_
    present = np.ones((80, 3), dtype=bool)
    present[::2, 1] = False  # two missing patterns in one batch: grouped internally
    present[1::4, 0] = False
    contours = test.contours.astype(np.float64).copy()
    contours[~present] = np.nan  # absent rows may hold anything
    s2 = 1e-3
    res = model.infer(contours, present, noise_variance=s2)
    norm, _, _ = normalise(test.contours.astype(np.float64))
    for pattern in np.unique(present, axis=0):
        rows = np.flatnonzero((present == pattern).all(1))
        observed = lay.observed_mask(pattern)
        x_obs = norm[rows].reshape(len(rows), -1)[:, observed[: lay.contour_dim]]
        ref = dense_reference(model.mixture_, x_obs, np.flatnonzero(observed), s2)
        resp, logm = ref["responsibilities"], ref["log_marginal"]
        full = np.empty((len(rows), lay.dim))
        full[:, ~observed] = ref["mean"]  # C_ba C_aa^-1 (a - mu_a)
        full[:, observed] = ref["reconstruction"][:, observed]  # mu_a + W_a E[z | a]
        c_ref, j_ref = lay.split(full)
        np.testing.assert_allclose(res.joints[rows], j_ref, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(res.contours_norm[rows], c_ref, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(res.responsibilities[rows], resp, atol=1e-8)
        np.testing.assert_allclose(res.log_marginal[rows], logm, rtol=1e-9)
    # the same frames given only the present view columns (input_views) give the same answer
    sub = model.infer(test.contours[:, [0, 2]], noise_variance=s2, input_views=(0, 2))
    rows = np.flatnonzero((present == [True, False, True]).all(1))
    np.testing.assert_allclose(sub.joints[rows], res.joints[rows], rtol=1e-9, atol=1e-12)
    # missing views: NaN in pixels unless the true normalisation factors are given
    assert np.isnan(res.contours_px[~present]).all() and np.isfinite(res.contours_px[present]).all()
    _, cen, sc = normalise(test.contours.astype(np.float64))  # the true factors (eval passes them)
    placed = model.infer(contours, present, s2, centroid=cen, scale=sc)
    assert np.isfinite(placed.contours_px).all()
    assert np.abs(placed.contours_px[~present] - test.contours[~present]).mean() < 3.0


def test_zero_filling_differs_and_is_worse(fitted):
    model, _, test = fitted
    present = np.ones((80, 3), dtype=bool)
    present[:, 1] = False
    marg = model.infer(test.contours, present)
    zero = test.contours.astype(np.float64).copy()
    zero[:, 1] = 0.0  # normalises to an all-zero contour: zero-filling in feature space
    filled = model.infer(zero)  # view 1 "observed" as zeros
    assert not np.allclose(marg.joints, filled.joints, atol=1e-3)
    assert _err_cm(marg.joints, test.joints) < _err_cm(filled.joints, test.joints)
    full = model.infer(test.contours)
    # fewer views: larger posterior uncertainty on average
    assert marg.joint_std.mean() > full.joint_std.mean()


def test_single_view_model_takes_rig_views(fitted):
    _, train, test = fitted
    m1 = ShapeStructureModel(2, 4, views=(2,), n_init=1, random_state=1).fit(train.contours, train.joints)
    a = m1.infer(test.contours)  # all rig views: selects view 2
    b = m1.infer(test.contours[:, 2:3])  # only the modelled view
    np.testing.assert_allclose(a.joints, b.joints, rtol=1e-10, atol=1e-12)
    assert a.contours_norm.shape == (80, 1, N_POINTS, 2) and a.views == (2,)


def test_input_validation(fitted):
    model, _, test = fitted
    c = test.contours
    with pytest.raises(ValueError, match=r"\(N, K, n, 2\)"):
        model.infer(c[0])
    with pytest.raises(ValueError, match="points per contour"):
        model.infer(c[:, :, :5])
    with pytest.raises(ValueError, match="expected 3"):
        model.infer(c[:, :2])
    with pytest.raises(ValueError, match="unknown view indices \\[7\\]"):
        model.infer(c[:, :2], input_views=(0, 7))
    bad = c.astype(np.float64).copy()
    bad[3, 2, 0, 0] = np.nan
    with pytest.raises(ValueError, match="frame 3, view 2"):
        model.infer(bad)
    with pytest.raises(ValueError, match="every modelled view is missing"):
        model.infer(c, np.zeros((80, 3), bool))
    with pytest.raises(ValueError, match="views_present must have shape"):
        model.infer(c, np.ones((80, 2), bool))
    with pytest.raises(ValueError, match="noise_variance"):
        model.infer(c, noise_variance=-1.0)
    with pytest.raises(RuntimeError, match="not fitted"):
        ShapeStructureModel().infer(c)
    with pytest.raises(ValueError, match="views \\[5\\] do not exist"):
        ShapeStructureModel(1, 2, views=(5,)).fit(c, test.joints)
    with pytest.raises(ValueError, match="NaN"):
        ShapeStructureModel(1, 2).fit(bad, test.joints)


def test_the_models_conditioner_equals_dense_conditioning(fitted, dense_reference):
    """The conditioner infer uses (structure block as detail dims, every dim reconstructed) against the
    dense reference: reconstruction, best component's joints, their variance, responsibilities, log p(a)."""
    model, _, test = fitted
    lay, mix = model.layout_, model.mixture_
    norm, _, _ = normalise(test.contours.astype(np.float64))
    observed = lay.observed_mask([True, False, True])
    x_obs = norm.reshape(80, -1)[:, observed[: lay.contour_dim]]
    det = np.arange(lay.structure_slice.start, lay.structure_slice.stop)
    post = Conditioner(mix, observed, 3e-3, detail=det, reconstruct=True)(x_obs)
    ref = dense_reference(mix, x_obs, np.flatnonzero(observed), 3e-3)
    miss = np.flatnonzero(~observed)
    np.testing.assert_allclose(post.reconstruction[:, miss], ref["mean"], rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(post.reconstruction, ref["reconstruction"], rtol=1e-8, atol=1e-10)
    struct = np.searchsorted(miss, det)
    np.testing.assert_allclose(post.best_mean, ref["best_mean"][:, struct], rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(post.variance, ref["variance"][:, struct], rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(post.responsibilities, ref["responsibilities"], atol=1e-9)
    np.testing.assert_allclose(post.log_marginal, ref["log_marginal"], rtol=1e-10)


def test_fast_normalisation_equals_shared_contours():
    from silpose.shared.contours import denormalise

    rng = np.random.default_rng(0)
    pts = rng.normal(50, 20, size=(3, 2, 9, 2))
    pts[1, 1] = 7.0  # a degenerate contour: all points equal
    q, c, s = normalise_contours(pts)
    q_ref, c_ref, s_ref = normalise(pts)
    np.testing.assert_allclose(q, q_ref, atol=1e-13)
    np.testing.assert_allclose(c, c_ref, atol=1e-12)
    np.testing.assert_allclose(s, s_ref, atol=1e-12)
    assert s[1, 1] == 0 and np.all(q[1, 1] == 0)
    np.testing.assert_allclose(denormalise_contours(q, c, s), denormalise(q_ref, c_ref, s_ref), atol=1e-12)


def test_conditioner_cache_is_bounded_by_bytes_and_changes_no_result(fitted, monkeypatch):
    """Conditioners are cached per view pattern and s^2, least recently used out once their bytes pass the
    budget (a large-M model's conditioner holds tens of MB): the cache stays within it, and inference is the
    same whether a conditioner came from the cache or was rebuilt."""
    import silpose.model.posterior as posterior

    model, _, test = fitted
    patterns = [np.array([True, True, False]), np.array([True, False, True]), np.array([False, True, True])]
    present = np.stack([patterns[i % 3] for i in range(len(test.contours))])
    model._posterior = None
    reference = model.infer(test.contours, present)
    one = model.posterior().conditioner(patterns[0], model.noise_variance).nbytes
    monkeypatch.setattr(posterior, "CACHE_BYTES", int(2.5 * one))
    model._posterior = None
    for _ in range(2):
        res = model.infer(test.contours, present)
        cached = model.posterior()._cache
        assert 1 <= len(cached) <= 2 and sum(c.nbytes for c in cached.values()) <= 2.5 * one
        np.testing.assert_allclose(res.joints, reference.joints, rtol=1e-12)
        np.testing.assert_allclose(res.contours_px, reference.contours_px, rtol=1e-12)
    model._posterior = None


def test_large_one_pattern_batches_in_blocks_equal_the_whole_batch_steps(fitted, monkeypatch):
    """A batch of >= 2 x MIN_THREAD_FRAMES frames with one present-view pattern is normalised, conditioned and
    denormalised in blocks on threads (``Posterior.infer_in_blocks``): every field equals the whole-batch steps on one
    thread (the reference: the block path and the conditioner's threads switched off), also with an absent view (its
    given factors kept, its contours never read) and with the component means (hypotheses); an overflowing frame is
    named by its batch index and view."""
    import dataclasses

    from silpose.model import posterior, threads

    model, train, test = fitted
    c = np.concatenate([train.contours, test.contours, train.contours[:120]])  # 600 frames
    n, k = c.shape[:2]
    absent = np.ones((n, k), bool)
    absent[:, 1] = False
    c_absent = c.copy()
    c_absent[:, 1] = np.nan
    cen = np.concatenate([train.centroid, test.centroid, train.centroid[:120]])
    sc = np.concatenate([train.scale, test.scale, train.scale[:120]])
    calls = [dict(contours_px=c), dict(contours_px=c_absent, views_present=absent, centroid=cen, scale=sc),
             dict(contours_px=c, hypotheses=2)]

    def run():
        model._posterior = None  # a new cache of conditioners each time
        return [model.infer(**kw) for kw in calls]

    monkeypatch.setattr(posterior, "MIN_THREAD_FRAMES", 10**9)  # the reference: whole-batch steps ...
    monkeypatch.setattr(threads, "THREADS", 1)  # ... on one thread
    want = run()
    monkeypatch.setattr(posterior, "MIN_THREAD_FRAMES", threads.MIN_THREAD_FRAMES)
    monkeypatch.setattr(threads, "THREADS", 2)
    seen = []
    run_blocks = posterior.map_blocks
    monkeypatch.setattr(posterior, "map_blocks", lambda fn, b, t: seen.append((len(b), t)) or run_blocks(fn, b, t))
    got = run()
    assert seen == [(2, 2)] * 3  # 600 frames: 2 blocks of <= THREAD_BLOCK_ROWS (512) on 2 threads, each call
    for g, w in zip(got, want):
        for f in dataclasses.fields(w):
            a, b = getattr(g, f.name), getattr(w, f.name)
            if isinstance(b, np.ndarray):
                np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12, err_msg=f.name)
        assert (g.hypotheses is None) == (w.hypotheses is None)
        if w.hypotheses is not None:
            np.testing.assert_allclose(g.hypotheses.joints, w.hypotheses.joints, rtol=1e-12, atol=1e-12)
    assert np.isnan(got[1].contours_px[:, 1]).sum() == 0  # the absent view: mapped with its given factors
    np.testing.assert_array_equal(got[1].centroid[:, 1], cen[:, 1])
    bad = c.astype(np.float64)
    bad[550, 2, 3] = 1e300  # finite, but its squares overflow
    with pytest.raises(ValueError, match="overflow.*frame 550, view 2"):
        model.infer(bad)
    # only the present views are normalised: an overflow is named by its view among them, an absent view is never read
    bad = c_absent.astype(np.float64)
    bad[550, 2, 3] = 1e300  # the second present view
    with pytest.raises(ValueError, match="overflow.*frame 550, view 2"):
        model.infer(bad, views_present=absent, centroid=cen, scale=sc)
    junk = c_absent.astype(np.float64)
    junk[:, 1] = 1e300
    np.testing.assert_array_equal(model.infer(junk, views_present=absent, centroid=cen, scale=sc).joints, got[1].joints)
