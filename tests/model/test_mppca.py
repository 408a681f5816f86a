"""MPPCA estimator: exact density, monotone EM, closed-form PPCA, parameter recovery, errors."""

import warnings

import numpy as np
import pytest
from scipy.linalg import subspace_angles
from scipy.optimize import linear_sum_assignment
from scipy.stats import multivariate_normal
from sklearn.decomposition import PCA
from sklearn.exceptions import ConvergenceWarning

from silpose.model import _ppca
from silpose.model.mppca import MPPCA


def _random_mixture(rng, m, d, q, sep=6.0, noise=(0.05, 0.2)):
    weights = rng.dirichlet(np.full(m, 8.0))
    means = sep * rng.standard_normal((m, d))
    comps = np.stack([np.linalg.qr(rng.standard_normal((d, q)))[0] * np.linspace(3.0, 1.5, q) for _ in range(m)])
    s2 = rng.uniform(*noise, m)
    return weights, means, comps, s2


def _draw(rng, n, weights, means, comps, s2):
    labels = rng.choice(len(weights), size=n, p=weights)
    z = rng.standard_normal((n, comps.shape[2]))
    X = means[labels] + np.einsum("ndq,nq->nd", comps[labels], z)
    X += np.sqrt(s2[labels])[:, None] * rng.standard_normal(X.shape)
    return X, labels


def _dense_log_density(est, X):
    """Reference: scipy multivariate normal with the dense d x d covariance of each component."""
    dens = [np.log(w) + multivariate_normal(mu, W @ W.T + s2 * np.eye(len(mu))).logpdf(X)
            for w, mu, W, s2 in zip(est.weights_, est.means_, est.components_, est.noise_variance_)]
    return np.logaddexp.reduce(np.array(dens), axis=0)


@pytest.fixture(scope="module")
def mixture_data():
    rng = np.random.default_rng(20031013)
    params = _random_mixture(rng, m=3, d=12, q=2)
    X, labels = _draw(rng, 3000, *params)
    return X, labels, params


def test_log_density_equals_dense_multivariate_normal(mixture_data):
    X, _, _ = mixture_data
    est = MPPCA(3, 2, random_state=0, n_init=1).fit(X)
    Xq = np.vstack([X[:50], X[:5] + 10.0])  # include far-out points
    ref = _dense_log_density(est, Xq)
    np.testing.assert_allclose(est.score_samples(Xq), ref, rtol=1e-8)
    # the per-component helper against scipy, on arbitrary (not fitted) parameters
    rng = np.random.default_rng(1)
    W, mu = rng.standard_normal((7, 3)), rng.standard_normal(7)
    pts = rng.standard_normal((20, 7)) * 3
    np.testing.assert_allclose(_ppca.component_log_density(pts, mu, W, 0.3),
                               multivariate_normal(mu, W @ W.T + 0.3 * np.eye(7)).logpdf(pts), rtol=1e-10)
    assert est.score(Xq) == pytest.approx(np.mean(ref), rel=1e-8)


def test_em_never_decreases_log_likelihood(mixture_data):
    X, _, _ = mixture_data
    seen = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        est = MPPCA(4, 3, init="random", n_init=1, tol=0.0, max_iter=40, random_state=3,
                    callback=lambda it, lb: seen.append((it, lb))).fit(X)
    lb = np.asarray(est.lower_bounds_)
    assert len(lb) == est.n_iter_ == 40
    assert np.all(np.diff(lb) >= -1e-10 * np.abs(lb[1:])), np.diff(lb).min()
    assert lb[-1] > lb[0]  # EM made progress from the random start
    assert [it for it, _ in seen] == list(range(1, 41))
    np.testing.assert_allclose([v for _, v in seen], lb)
    assert est.lower_bound_ == pytest.approx(est.score(X), rel=1e-12)


def test_one_component_fit_is_closed_form_ppca_and_matches_sklearn_pca():
    rng = np.random.default_rng(7)
    n, d, q = 400, 9, 3
    X = rng.standard_normal((n, d)) @ rng.standard_normal((d, d)) + rng.standard_normal(d)
    est = MPPCA(1, q, random_state=0).fit(X)
    C_model = est.components_[0] @ est.components_[0].T + est.noise_variance_[0] * np.eye(d)
    C_pca = PCA(n_components=q).fit(X).get_covariance() * (n - 1) / n
    np.testing.assert_allclose(C_model, C_pca, rtol=1e-6, atol=1e-9)
    # closed form from the ML covariance eigenvalues (T&B 1999 PPCA eqs. 7-8)
    lam = np.linalg.eigvalsh(np.cov(X.T, bias=True))[::-1]
    assert est.noise_variance_[0] == pytest.approx(lam[q:].mean(), rel=1e-10)
    np.testing.assert_allclose(est.means_[0], X.mean(axis=0), rtol=1e-12)
    # EM itself (not just the initialisation) reaches the same optimum from a random W
    W, s2 = rng.standard_normal((1, d, q)), np.ones(1)
    Xc = X - X.mean(axis=0)
    resp = np.ones((n, 1))
    for _ in range(2000):
        sqn, XW, _ = _ppca.e_step_products(Xc, np.zeros((1, d)), W)
        _, mu, W, s2 = _ppca.m_step(Xc, sqn, resp, XW, W, s2, 1e-12)
    np.testing.assert_allclose(W[0] @ W[0].T + s2[0] * np.eye(d), C_pca, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(mu[0], 0.0, atol=1e-12)


def test_recovers_known_mixture_parameters():
    rng = np.random.default_rng(42)
    m, d, q = 3, 15, 2
    weights, means, comps, s2 = _random_mixture(rng, m, d, q)
    X, _ = _draw(rng, 6000, weights, means, comps, s2)
    est = MPPCA(m, q, random_state=0, n_init=2).fit(X)
    cost = ((est.means_[:, None, :] - means[None]) ** 2).sum(-1)
    row, col = linear_sum_assignment(cost)
    perm = col[np.argsort(row)]  # est component k <-> true component perm[k]
    np.testing.assert_allclose(est.weights_, weights[perm], atol=0.02)
    assert np.max(np.abs(est.means_ - means[perm])) < 0.25
    for k in range(m):
        assert np.max(subspace_angles(est.components_[k], comps[perm[k]])) < 0.1
        # W is identified up to rotation: compare W W^T
        np.testing.assert_allclose(est.components_[k] @ est.components_[k].T,
                                   comps[perm[k]] @ comps[perm[k]].T, atol=0.6)
    np.testing.assert_allclose(est.noise_variance_, s2[perm], rtol=0.1)
    assert est.converged_
    lb = np.asarray(est.lower_bounds_)  # the winning em-EM run, short phase + continuation
    assert len(lb) == est.n_iter_ and np.all(np.diff(lb) >= -1e-10 * np.abs(lb[1:]))
    # the posterior labels agree with the generating ones up to the permutation
    X2, lab2 = _draw(rng, 500, weights, means, comps, s2)
    assert np.mean(perm[est.predict(X2)] == lab2) > 0.99
    np.testing.assert_allclose(est.predict_proba(X2).sum(axis=1), 1.0)


def test_bic_selects_true_number_of_components(mixture_data):
    X, _, _ = mixture_data
    bics = [MPPCA(m, 2, random_state=0, n_init=1).fit(X).bic(X) for m in (1, 2, 3, 5)]
    assert int(np.argmin(bics)) == 2
    est = MPPCA(3, 2, random_state=0, n_init=1).fit(X)
    assert est.aic(X) < est.bic(X)  # log N > 2


def test_sample_reproduces_model_moments(mixture_data):
    X, _, _ = mixture_data
    est = MPPCA(3, 2, random_state=0, n_init=1).fit(X)
    S, lab = est.sample(40000, random_state=5)
    assert S.shape == (40000, X.shape[1]) and lab.shape == (40000,)
    np.testing.assert_allclose(np.bincount(lab, minlength=3) / 40000, est.weights_, atol=0.01)
    k = int(np.argmax(est.weights_))
    Sk = S[lab == k]
    C = est.components_[k] @ est.components_[k].T + est.noise_variance_[k] * np.eye(X.shape[1])
    np.testing.assert_allclose(Sk.mean(axis=0), est.means_[k], atol=0.08)
    np.testing.assert_allclose(np.cov(Sk.T), C, atol=0.25)
    a, _ = est.sample(10, random_state=1)
    b, _ = est.sample(10, random_state=1)
    np.testing.assert_array_equal(a, b)


def test_fit_is_deterministic_given_random_state(mixture_data):
    X, _, _ = mixture_data
    a = MPPCA(3, 2, random_state=11, n_init=2).fit(X)
    b = MPPCA(3, 2, random_state=11, n_init=2).fit(X)
    np.testing.assert_array_equal(a.components_, b.components_)
    np.testing.assert_array_equal(a.noise_variance_, b.noise_variance_)


def test_warns_when_em_does_not_converge(mixture_data):
    X, _, _ = mixture_data
    with pytest.warns(ConvergenceWarning, match="did not converge"):
        est = MPPCA(4, 2, init="random", n_init=1, max_iter=2, tol=0.0, random_state=0).fit(X)
    assert not est.converged_ and est.n_iter_ == 2


@pytest.mark.parametrize(
    "kwargs, X, match",
    [
        ({}, np.ones(20), "2D array"),
        ({}, np.full((20, 12), np.nan), "NaN"),
        ({}, np.where(np.eye(20, 12) > 0, np.inf, 0.0), "infinity"),
        ({"n_components": 5, "n_latent": 1}, np.random.default_rng(0).standard_normal((4, 3)), "n_samples = 4"),
        ({"n_components": 1, "n_latent": 3}, np.random.default_rng(0).standard_normal((10, 3)), "n_latent = 3"),
        ({"n_components": 0}, np.random.default_rng(0).standard_normal((10, 30)), "n_components"),
        ({"n_latent": 2, "init": "spectral"}, np.random.default_rng(0).standard_normal((10, 5)), "init"),
        ({"n_latent": 2, "tol": -1.0}, np.random.default_rng(0).standard_normal((10, 5)), "tol"),
    ],
)
def test_malformed_fit_input_raises(kwargs, X, match):
    with pytest.raises(ValueError, match=match):
        MPPCA(**kwargs).fit(X)


def test_predict_with_wrong_feature_count_raises(mixture_data):
    X, _, _ = mixture_data
    est = MPPCA(2, 2, random_state=0, n_init=1).fit(X[:300])
    with pytest.raises(ValueError, match="features"):
        est.score_samples(X[:5, :-1])
    with pytest.raises(ValueError, match="NaN"):
        est.predict(np.full((2, X.shape[1]), np.nan))


def test_em_em_continues_the_best_short_run(mixture_data):
    """n_init short runs (5 iterations), then the best one continues: lower_bounds_ starts with the
    short run whose last bound was highest."""
    X, _, _ = mixture_data
    seen = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        est = MPPCA(5, 2, init="random", n_init=4, tol=1e-6, max_iter=12, random_state=1,
                    callback=lambda it, lb: seen.append((it, lb))).fit(X)
    starts = [k for k, (it, _) in enumerate(seen) if it == 1] + [len(seen)]
    short = [[lb for it, lb in seen[a:b] if it <= 5] for a, b in zip(starts[:-1], starts[1:])]
    assert len(short) == 4 and all(len(r) <= 5 for r in short)
    assert len({r[-1] for r in short}) > 1  # the starts really differ
    winner = int(np.argmax([r[-1] for r in short]))
    np.testing.assert_array_equal(est.lower_bounds_[: len(short[winner])], short[winner])
    assert est.lower_bound_ >= max(r[-1] for r in short)
    assert [it for it, _ in seen[starts[-2]:]][-1] == est.n_iter_  # the continuation counts on


def test_pooled_mixture_is_the_average_of_the_fits_densities(mixture_data):
    """pool_mixtures: log p(x) = log((1/F) sum_f p_f(x)), checked against each fit's own density, and the
    pooled model is an MPPCA like any other (dense reference, weights summing to 1, real EM per fit)."""
    from scipy.special import logsumexp

    from silpose.model.mppca import pool_mixtures
    from silpose.model.selection import is_real_em

    X = mixture_data[0][:600]
    fits = [MPPCA(3, 2, n_init=1, random_state=s, max_iter=50).fit(X) for s in range(3)]
    pooled = pool_mixtures(fits, X)
    expected = logsumexp(np.stack([f.score_samples(X) for f in fits]), axis=0) - np.log(3)
    np.testing.assert_allclose(pooled.score_samples(X), expected, rtol=1e-10)
    np.testing.assert_allclose(pooled.score_samples(X[:50]), _dense_log_density(pooled, X[:50]), rtol=1e-8)
    assert pooled.weights_.shape == (9,) and abs(pooled.weights_.sum() - 1) < 1e-12
    assert pooled.lower_bound_ == pytest.approx(expected.mean(), rel=1e-10)
    assert [r["n_iter"] for r in pooled.runs_] == [f.n_iter_ for f in fits]
    assert is_real_em(pooled, 0.1) == all(is_real_em(f, 0.1) for f in fits)
    with pytest.raises(ValueError, match="differ in latent dimension"):
        pool_mixtures([fits[0], MPPCA(2, 3, n_init=1, random_state=0, max_iter=5).fit(X)])


def test_pass_level_density_factors_equal_the_dense_density():
    """The E-step's per-component constants are computed once per parameter set (``Params.density_factors``);
    the log densities they give equal scipy's dense multivariate normal, and a shifted parameter set keeps
    them (they depend on W and s2 only)."""
    from silpose.model import _em

    rng = np.random.default_rng(3)
    m, d, q = 3, 12, 2
    params = _em.Params(np.full(m, 1 / m), rng.normal(size=(m, d)), rng.normal(size=(m, d, q)),
                        rng.uniform(0.1, 0.5, m))
    X = rng.normal(size=(40, d)) + params.means[0]
    sqn, XW, Xmu = _ppca.e_step_products(X, params.means, params.components)
    got = _ppca.log_prob_from_products(sqn, XW, Xmu, params.weights, params.means, params.components,
                                       params.noise_variance, params.density_factors())
    for i in range(m):
        cov = params.components[i] @ params.components[i].T + params.noise_variance[i] * np.eye(d)
        ref = np.log(params.weights[i]) + multivariate_normal(params.means[i], cov).logpdf(X)
        np.testing.assert_allclose(got[:, i], ref, rtol=1e-10, atol=1e-8)
    shifted = params.shifted(np.ones(d))
    assert shifted.density_factors() is params.density_factors()


def test_one_blas_thread_limits_blas_and_restores_it():
    """EM's log densities run on one BLAS thread (silpose.model.threads.one_blas_thread); the previous limit comes back,
    and the E-step under it gives the unlimited values to rounding."""
    from threadpoolctl import threadpool_info

    from silpose.model import _em
    from silpose.model.threads import one_blas_thread

    def blas_threads():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    before = blas_threads()
    with one_blas_thread():
        assert blas_threads() and set(blas_threads()) == {1}
    assert blas_threads() == before
    rng = np.random.default_rng(3)
    X = rng.normal(size=(300, 40))
    params = _em.Params(np.full(5, 0.2), rng.normal(size=(5, 40)), rng.normal(size=(5, 40, 6)) * 0.3, np.full(5, 0.7))
    sqn, XW, Xmu = _ppca.e_step_products(X, params.means, params.components)
    ref = _ppca.log_prob_from_products(sqn, XW, Xmu, params.weights, params.means, params.components,
                                       params.noise_variance)
    stats = _em.shard_stats(X, params)
    from scipy.special import logsumexp

    assert stats.loglik == pytest.approx(float(logsumexp(ref, axis=1).sum()), rel=1e-12)
