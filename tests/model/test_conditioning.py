"""Gaussian conditioning of a mixture of PPCA (silpose.model.conditioning): equals dense Gaussian conditioning (the
``dense_reference`` fixture, tests/model/conftest.py); marginalises missing dims."""

import numpy as np
import pytest

from silpose.model.conditioning import MixtureParams, BatchPosterior, Conditioner, condition, condition_rows
from silpose.model.mppca import MPPCA


class Params:
    def __init__(self, rng, m=3, d=10, q=3):
        self.weights_ = rng.dirichlet(np.full(m, 3.0))
        self.means_ = 2.0 * rng.standard_normal((m, d))
        self.components_ = rng.standard_normal((m, d, q))
        self.noise_variance_ = rng.uniform(0.1, 0.5, m)


@pytest.mark.parametrize("noise_kind", ["zero", "scalar", "per_dim"])
@pytest.mark.parametrize("observed_kind", ["mask", "index"])
def test_condition_equals_dense_gaussian_conditioning(noise_kind, observed_kind, dense_reference):
    rng = np.random.default_rng(5)
    p = Params(rng)
    d = p.means_.shape[1]
    obs = np.sort(rng.choice(d, size=6, replace=False))
    noise = {"zero": 0.0, "scalar": 0.3, "per_dim": rng.uniform(0.0, 1.0, obs.size)}[noise_kind]
    X_obs = p.means_[rng.integers(3, size=25)][:, obs] + rng.standard_normal((25, obs.size))
    observed = np.isin(np.arange(d), obs) if observed_kind == "mask" else obs
    res = condition(p, X_obs, observed, noise, return_components=True, return_cov=True)
    ref = dense_reference(p, X_obs, obs, noise)
    assert isinstance(res, BatchPosterior) and res.reconstruction is None
    np.testing.assert_array_equal(res.missing, np.setdiff1d(np.arange(d), obs))
    for key in ("mean", "best_mean", "component_means", "responsibilities", "variance", "cov", "component_cov"):
        np.testing.assert_allclose(getattr(res, key), ref[key], rtol=1e-9, atol=1e-11, err_msg=key)
    np.testing.assert_allclose(res.log_marginal, ref["log_marginal"], rtol=1e-10)
    # reconstruct=True: the posterior mean of every dim (the Bayesian reconstruction at observed dims)
    rec = condition(p, X_obs, observed, noise, reconstruct=True)
    np.testing.assert_allclose(rec.reconstruction, ref["reconstruction"], rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(rec.mean, ref["mean"], rtol=1e-9, atol=1e-11)
    assert rec.missing_mean is None


def test_detail_dims_and_parameter_objects(dense_reference):
    """``detail`` picks the missing dims whose spread is reported; MixtureParams and a fitted MPPCA are
    interchangeable; a detail dim that is observed is refused."""
    rng = np.random.default_rng(8)
    p = Params(rng)
    obs = np.array([0, 2, 3, 6, 9])
    det = np.array([8, 1])
    X_obs = rng.standard_normal((7, obs.size))
    ref = dense_reference(p, X_obs, obs, 0.05)
    cols = np.searchsorted(ref["missing"], det)
    params = MixtureParams(p.weights_, p.means_, p.components_, p.noise_variance_)
    for reconstruct in (False, True):
        res = condition(params, X_obs, obs, 0.05, detail=det, reconstruct=reconstruct, return_cov=True)
        np.testing.assert_array_equal(res.detail, det)
        np.testing.assert_allclose(res.best_mean, ref["best_mean"][:, cols], rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(res.variance, ref["variance"][:, cols], rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(res.cov, ref["cov"][:, cols][:, :, cols], rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(res.mean, ref["mean"], rtol=1e-9, atol=1e-11)
    with pytest.raises(ValueError, match="'detail' must index missing dims"):
        Conditioner(params, obs, 0.05, detail=np.array([2]))


def test_values_whose_density_overflows_are_refused():
    p = Params(np.random.default_rng(1))
    with pytest.raises(ValueError, match="row 1 is not finite"):
        condition(p, np.array([[0.0, 1.0], [1e300, 0.0]]), np.arange(2))


def test_index_order_of_observed_is_respected():
    rng = np.random.default_rng(2)
    p = Params(rng)
    obs = np.array([7, 1, 4, 0])
    X_obs = rng.standard_normal((5, 4))
    a = condition(p, X_obs, obs, 0.1)
    order = np.argsort(obs)
    b = condition(p, X_obs[:, order], obs[order], 0.1)
    np.testing.assert_allclose(a.mean, b.mean, rtol=1e-12)
    np.testing.assert_allclose(a.log_marginal, b.log_marginal, rtol=1e-12)


def test_full_and_empty_observation_limits():
    rng = np.random.default_rng(3)
    X = rng.standard_normal((400, 8)) @ rng.standard_normal((8, 8))
    X[:200] += 4.0
    est = MPPCA(2, 2, random_state=0, n_init=1).fit(X)
    assert MixtureParams.of(est).means_ is est.means_  # float64 parameters are used as they are
    full = condition(est, X[:20], np.ones(8, bool))
    np.testing.assert_allclose(full.log_marginal, est.score_samples(X[:20]), rtol=1e-10)
    np.testing.assert_allclose(full.responsibilities, est.predict_proba(X[:20]), rtol=1e-8, atol=1e-12)
    assert full.mean.shape == (20, 0)
    empty = condition(est, np.zeros((3, 0)), np.zeros(8, bool))
    np.testing.assert_allclose(empty.responsibilities, np.tile(est.weights_, (3, 1)))
    np.testing.assert_allclose(empty.mean, np.tile(est.weights_ @ est.means_, (3, 1)), rtol=1e-12)
    np.testing.assert_allclose(empty.log_marginal, 0.0, atol=1e-12)


def test_marginalising_beats_zero_filling_a_missing_view():
    """A 'view' block is missing: dropping it (marginalising) predicts the 'joint' block better than
    filling the view with zeros and conditioning on them as if observed."""
    rng = np.random.default_rng(11)
    d_view, n_views, d_joint, q = 6, 3, 4, 3
    d = n_views * d_view + d_joint
    p = Params(rng, m=2, d=d, q=q)
    p.means_ += 3.0  # so that zero is far from a plausible view
    lab = rng.choice(2, size=500, p=p.weights_)
    X = p.means_[lab] + np.einsum("ndq,nq->nd", p.components_[lab], rng.standard_normal((500, q)))
    X += np.sqrt(p.noise_variance_[lab])[:, None] * rng.standard_normal(X.shape)
    joints = np.arange(n_views * d_view, d)
    view_missing = np.arange(d_view, 2 * d_view)
    obs = np.setdiff1d(np.arange(n_views * d_view), view_missing)
    marg = condition(p, X[:, obs], obs, 0.0)
    joint_cols = np.searchsorted(marg.missing, joints)
    err_marg = np.mean((marg.mean[:, joint_cols] - X[:, joints]) ** 2)
    filled = X[:, : n_views * d_view].copy()
    filled[:, view_missing] = 0.0
    zf = condition(p, filled, np.arange(n_views * d_view), 0.0)
    err_zero = np.mean((zf.mean - X[:, joints]) ** 2)
    assert not np.allclose(marg.mean[:, joint_cols], zf.mean)
    assert err_marg < 0.5 * err_zero
    # the code marginalises: the values at missing dims never enter condition_rows
    Xn = X.copy()
    Xn[:, view_missing] = np.nan
    Xn[:, joints] = np.nan
    rows = condition_rows(p, Xn, 0.0)
    np.testing.assert_allclose(rows.mean[:, joints], marg.mean[:, joint_cols], rtol=1e-12)


def test_condition_rows_groups_patterns_and_matches_condition():
    rng = np.random.default_rng(4)
    p = Params(rng, d=9)
    X = rng.standard_normal((30, 9)) + p.means_[0]
    miss = np.zeros_like(X, bool)
    miss[:10, :3] = True  # pattern A
    miss[10:20, 5:] = True  # pattern B, rows 20.. fully observed
    miss[25, :] = True  # one row with nothing observed
    Xn = np.where(miss, np.nan, X)
    noise = rng.uniform(0.0, 0.2, 9)
    res = condition_rows(p, Xn, noise)
    np.testing.assert_array_equal(res.missing, miss)
    for rows in (np.arange(10), np.arange(10, 20), np.array([25])):
        obs = np.flatnonzero(~miss[rows[0]])
        ref = condition(p, X[np.ix_(rows, obs)], obs, noise[obs])
        np.testing.assert_allclose(res.mean[np.ix_(rows, ref.missing)], ref.mean, rtol=1e-12)
        np.testing.assert_allclose(res.variance[np.ix_(rows, ref.missing)], ref.variance, rtol=1e-12)
        np.testing.assert_allclose(res.responsibilities[rows], ref.responsibilities, rtol=1e-12)
        np.testing.assert_allclose(res.log_marginal[rows], ref.log_marginal, rtol=1e-12)
        np.testing.assert_array_equal(res.mean[rows][:, obs], X[rows][:, obs])  # observed values kept
        np.testing.assert_array_equal(res.variance[rows][:, obs], 0.0)
    assert res.component_means.shape == (30, 3, 9)


def test_prepared_conditioner_is_reusable_and_single_row_works():
    rng = np.random.default_rng(6)
    p = Params(rng)
    obs = np.arange(5)
    cond = Conditioner(p, obs, 0.2)
    X = rng.standard_normal((8, 5))
    batch = cond(X)
    one = cond(X[3])
    np.testing.assert_allclose(one.mean[0], batch.mean[3], rtol=1e-12)
    np.testing.assert_allclose(cond.component_cov(), condition(p, X, obs, 0.2, return_cov=True).component_cov)


def test_rows_conditioned_in_chunks_equal_one_batch(monkeypatch):
    """Large M x q models condition in smaller row chunks (bounded temporaries): chunking must not change a
    single number of the posterior, the per-row reference being each row conditioned alone."""
    import silpose.model.conditioning as conditioning

    rng = np.random.default_rng(7)
    p = Params(rng)
    obs = np.arange(6)
    X = rng.standard_normal((50, 6))
    whole = Conditioner(p, obs, 0.1, reconstruct=True)(X, return_components=True)
    monkeypatch.setattr(conditioning, "_CHUNK_VALUES", 1)  # the value bound alone gives its 64-row floor ...
    monkeypatch.setattr(conditioning, "_CHUNK", 7)  # ... and the row bound 7: chunks of 7, 7, ..., 1 rows
    chunked = Conditioner(p, obs, 0.1, reconstruct=True)(X, return_components=True)
    for name in ("reconstruction", "best_mean", "variance", "responsibilities", "log_marginal", "component_means"):
        np.testing.assert_allclose(getattr(chunked, name), getattr(whole, name), rtol=1e-12, atol=1e-14, err_msg=name)
    one = Conditioner(p, obs, 0.1, reconstruct=True)(X[31])
    np.testing.assert_allclose(one.reconstruction[0], whole.reconstruction[31], rtol=1e-12)


def test_large_batches_condition_in_blocks_on_threads(monkeypatch, dense_reference):
    """A batch of >= 2 x MIN_THREAD_FRAMES rows is conditioned in blocks on the pool's threads (``threads.map_blocks``,
    BLAS on one thread): every row equals dense conditioning, and a NaN in a late block is still refused."""
    import silpose.model.conditioning as conditioning
    from silpose.model import threads

    rng = np.random.default_rng(11)
    p = Params(rng)
    obs = np.array([0, 2, 3, 5, 7, 8])
    n = 2 * threads.MIN_THREAD_FRAMES + 37
    X = p.means_[rng.integers(3, size=n)][:, obs] + rng.standard_normal((n, obs.size))
    seen = []
    run = conditioning.map_blocks

    def spy(fn, blocks, count):
        seen.append((len(blocks), count))
        return run(fn, blocks, count)

    monkeypatch.setattr(threads, "THREADS", 2)  # two threads whatever the machine's cores
    monkeypatch.setattr(conditioning, "map_blocks", spy)
    res = Conditioner(p, obs, 0.2, reconstruct=True)(X, return_components=True)
    assert seen == [(2, 2)]  # 549 rows: 2 blocks of <= THREAD_BLOCK_ROWS (512) on 2 threads
    ref = dense_reference(p, X, obs, 0.2)
    for key in ("reconstruction", "best_mean", "component_means", "responsibilities", "variance"):
        np.testing.assert_allclose(getattr(res, key), ref[key], rtol=1e-9, atol=1e-11, err_msg=key)
    np.testing.assert_allclose(res.log_marginal, ref["log_marginal"], rtol=1e-10)
    X[n - 3, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        Conditioner(p, obs, 0.2)(X)

@pytest.mark.parametrize(
    "call, match",
    [
        (lambda p: condition(p, np.zeros((4, 3)), np.arange(4)), r"shape \(N, 4\)"),
        (lambda p: condition(p, np.full((2, 4), np.nan), np.arange(4)), "NaN"),
        (lambda p: condition(p, np.zeros((2, 4)), np.ones(4, bool)), r"mask must have shape \(10,\)"),
        (lambda p: condition(p, np.zeros((2, 2)), np.array([0, 10])), r"in \[0, 10\)"),
        (lambda p: condition(p, np.zeros((2, 2)), np.array([3, 3])), "repeated"),
        (lambda p: condition(p, np.zeros((2, 2)), np.array([0, 1]), -1.0), ">= 0"),
        (lambda p: condition(p, np.zeros((2, 2)), np.array([0, 1]), np.ones(3)), r"shape \(2,\)"),
        (lambda p: condition_rows(p, np.zeros((2, 9))), r"shape \(N, 10\)"),
        (lambda p: condition_rows(p, np.full((2, 10), np.inf)), "inf"),
    ],
)
def test_malformed_conditioning_input_raises(call, match):
    with pytest.raises(ValueError, match=match):
        call(Params(np.random.default_rng(0)))


def test_unfitted_or_foreign_model_raises():
    with pytest.raises(TypeError, match="weights_"):
        condition(MPPCA(), np.zeros((1, 2)), np.arange(2))
    p = Params(np.random.default_rng(0))
    p.means_ = p.means_[:, :5]
    with pytest.raises(ValueError, match="inconsistent parameter shapes"):
        condition(p, np.zeros((1, 2)), np.arange(2))
