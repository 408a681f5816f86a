"""Degrees-of-freedom correction of the PPCA noise variance, and what MPPCA records about its EM run."""

import numpy as np
import pytest

from silpose.model import _ppca
from silpose.model.mppca import MPPCA


def _ppca_data(rng, n, d, q, sigma2=1.0, signal=25.0):
    basis = np.linalg.qr(rng.normal(size=(d, q)))[0]
    return rng.normal(size=(n, q)) * np.sqrt(signal) @ basis.T + rng.normal(size=(n, d)) * np.sqrt(sigma2)


def test_corrected_noise_variance_is_unbiased_where_the_maximum_likelihood_one_is_not():
    """Few rows per latent dimension (n = 40, q = 5, d = 200): the ML variance is the residual of a subspace
    fitted to the same rows, biased low; the corrected one matches the true sigma^2 = 1 on average."""
    rng = np.random.default_rng(0)
    n, d, q = 40, 200, 5
    ml, corrected = [], []
    for _ in range(30):
        X = _ppca_data(rng, n, d, q)
        _, _, s2 = _ppca.ppca_closed_form(X, q, 1e-12, rng)
        factor, under = _ppca.dof_noise_factor(np.array([n]), d, q)
        assert not under[0]
        ml.append(s2)
        corrected.append(s2 * factor[0])
    assert np.mean(ml) < 0.9  # ~ (n - 1 - q) / n of the truth
    assert np.mean(corrected) == pytest.approx(1.0, abs=0.02)


def test_dof_factor_formula_and_underdetermined_components():
    factor, under = _ppca.dof_noise_factor(np.array([1000.0, 10.0, 6.0, 3.0]), d=100, q=5)
    assert factor[0] == pytest.approx(1000 / 994) and factor[1] == pytest.approx(10 / 4)
    assert list(under) == [False, False, True, True]  # n <= q + 1 rows leave no degrees of freedom
    assert np.all(factor[under] == 1.0) and np.all(factor >= 1.0)


def test_mppca_records_its_start_and_corrects_only_the_noise_variance():
    rng = np.random.default_rng(1)
    X = np.concatenate([_ppca_data(rng, 60, 80, 3) + 20.0, _ppca_data(rng, 60, 80, 3) - 20.0])
    plain = MPPCA(2, 3, n_init=1, random_state=0, tol=0.0, max_iter=5).fit(X)
    dof = MPPCA(2, 3, n_init=1, random_state=0, tol=0.0, max_iter=5, noise_dof=True).fit(X)
    np.testing.assert_array_equal(plain.means_, dof.means_)
    np.testing.assert_array_equal(plain.components_, dof.components_)
    np.testing.assert_allclose(dof.noise_variance_, plain.noise_variance_ * dof.noise_dof_factor_, rtol=1e-12)
    assert np.all(dof.noise_dof_factor_ > 1.0) and dof.n_underdetermined_ == 0
    assert plain.lower_bounds_ == dof.lower_bounds_  # EM itself is unchanged
    assert dof.lower_bound_ == pytest.approx(dof.score(X), rel=1e-9)  # the final (corrected) parameters
    assert dof.lower_bound_ < plain.lower_bound_  # ML maximises the training likelihood; the correction gives some up
    assert plain.initial_bound_ <= plain.lower_bounds_[0] + 1e-9  # EM never loses likelihood from its start
    assert np.all(plain.noise_dof_factor_ == 1.0)
