"""The EM benchmark: its synthetic data are fit as well as theory allows, and its rows are consistent."""

import math
import warnings

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.exceptions import ConvergenceWarning

from benchmarks import em
from silpose.model import MPPCA


def test_truth_model_scores_with_the_dense_gaussian_density():
    """``synthetic_mixture``'s truth (an MPPCA holding the generating parameters) gives the mixture
    log density computed independently with full d x d covariances (scipy)."""
    X, labels, truth = em.synthetic_mixture(300, 12, 3, 2, seed=4)
    assert X.shape == (300, 12) and set(np.unique(labels)) <= {0, 1}
    dens = sum(w * multivariate_normal(mu, W @ W.T + s2 * np.eye(12)).pdf(X)
               for w, mu, W, s2 in zip(truth.weights_, truth.means_, truth.components_, truth.noise_variance_))
    assert truth.score(X) == pytest.approx(np.mean(np.log(dens)), rel=1e-10)


def test_fit_on_bench_data_reaches_generating_parameters_likelihood():
    """The benchmark's synthetic data (small version): the held-out log-likelihood of the fit is
    within the expected optimism of a k-parameter ML fit (about k / N nats per sample, the AIC
    argument) of that of the generating parameters; the paper-scale run is the ``em`` section."""
    n_train = 4000
    X, _, truth = em.synthetic_mixture(n_train + 1000, 60, 4, 3, seed=3, mean_scale=1.0)
    est = MPPCA(3, 4, random_state=0).fit(X[:n_train])
    assert abs(est.score(X[n_train:]) - truth.score(X[n_train:])) < est.n_parameters() / n_train


@pytest.mark.slow
def test_paper_scale_fit_reaches_generating_parameters_likelihood():
    """Paper scale (N = 20,000, d = 1657, q = 30, M = 5; about a minute): same criterion as the
    small version above."""
    n_train = 20000
    X, _, truth = em.synthetic_mixture(n_train + 2000, 1657, 30, 5, seed=1)
    est = MPPCA(5, 30, random_state=0).fit(X[:n_train])
    assert abs(est.score(X[n_train:]) - truth.score(X[n_train:])) < est.n_parameters() / n_train


def test_em_rows_ratios_are_recomputed_from_their_own_timings():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        rows = em.run(n=400, d=60, q=3, m=2, gmm_iters=2, n_init=1, iter_runs=4, floor_repeats=2)
    by = {r["quantity"].split(" (")[0]: r for r in rows}
    it = by["time per EM iteration"]
    assert it["unit"] == "s" and it["value"] > 0 and it["reference"] > 0
    assert math.isclose(it["ratio"], it["reference"] / it["value"], rel_tol=1e-12)
    # the floor: positive, below the kernel that contains its products, and the ratio is kernel / floor
    assert it["blas_floor_s"] > 0 and it["value"] > 0  # timed in one run; their order is timing, not asserted
    assert math.isclose(it["over_floor"], it["value"] / it["blas_floor_s"], rel_tol=1e-12)
    assert "(400x60)@(60x6)" in it["floor_products"] and "(60x400)@(400x6)" in it["floor_products"]
    assert "dense" not in " ".join(str(r["note"]) for r in rows)  # no dense-conditioning reference any more
    ll = by["held-out mean log-likelihood"]
    assert ll["unit"] == "nats/sample" and np.isfinite(ll["value"]) and np.isfinite(ll["reference"])
    assert by["peak RSS during MPPCA fit"]["value"] > 0
