"""MPPCA's defaults fit small data (issue 13: ``MPPCA()`` with its default ``n_latent = 10`` refused any
data of 10 features or fewer, where scikit-learn's PCA and GaussianMixture work with their defaults)."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.decomposition import PCA
from sklearn.mixture import GaussianMixture

from silpose.model.mppca import MPPCA


def blobs(d, n=300, seed=0):
    rng = np.random.default_rng(seed)
    centres = rng.normal(scale=6.0, size=(3, d))
    return centres[rng.integers(3, size=n)] + rng.normal(size=(n, d))


@pytest.mark.parametrize("d", [2, 3, 5, 10])
def test_default_mppca_fits_data_of_ten_features_or_fewer(d):
    X = blobs(d)
    PCA().fit(X), GaussianMixture().fit(X)  # the scikit-learn estimators the issue compares with
    est = MPPCA(random_state=0).fit(X)
    assert est.n_latent is None and est.n_latent_ == d - 1
    assert est.components_.shape == (5, d, d - 1)
    assert np.isfinite(est.score(X))


def test_default_latent_dimension_is_ten_when_there_are_more_features():
    est = MPPCA(n_components=2, n_init=1, random_state=0).fit(blobs(30))
    assert est.n_latent_ == 10 and est.components_.shape == (2, 30, 10)


def test_an_explicit_n_latent_is_used_and_checked_as_before():
    X = blobs(6)
    assert MPPCA(n_latent=2, random_state=0).fit(X).n_latent_ == 2
    with pytest.raises(ValueError, match="n_latent = 6 must be smaller than n_features = 6"):
        MPPCA(n_latent=6).fit(X)


def test_one_feature_is_refused_with_a_clear_message():
    with pytest.raises(ValueError, match="n_features = 1, but a mixture of PPCA needs at least 2 features"):
        MPPCA().fit(blobs(1))
