"""The sparse E-step of the MPPCA (``MPPCA(e_step="sparse")``, silpose.model._em.shard_stats_sparse) against the
exact one: the same EM when every component is a candidate, the same optimum on separated clusters when
only a few are, the same fit streamed locally and on Ray."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.datagen.testing import write_synthetic_dataset
from silpose.model import streaming
from silpose.model.mppca import SPARSE_MIN_COMPONENTS, SPARSE_MIN_COMPONENTS_LARGE_N, SPARSE_MIN_ROWS, MPPCA
from silpose.model.shape_model import ShapeStructureModel

pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")


def _mixture(n=1500, d=60, q=3, m=6, seed=0, sep=3.0):
    """Rows of m separated rank-q Gaussians in d dims (mean separation ~ sep * sqrt(2 d) vs unit spread)."""
    rng = np.random.default_rng(seed)
    means = sep * rng.standard_normal((m, d))
    labels = rng.integers(m, size=n)
    W = rng.standard_normal((m, d, q))
    X = means[labels] + np.einsum("nq,ndq->nd", rng.standard_normal((n, q)), W[labels])
    return X + 0.3 * rng.standard_normal((n, d)), labels


def _start(X, m, q, seed=3):
    """A start away from the optimum: one exact EM iteration of a random-init fit on every 4th row."""
    f = MPPCA(m, q, n_init=1, max_iter=1, init="random", random_state=seed, e_step="exact").fit(X[::4])
    return dict(weights=f.weights_, means=f.means_, components=f.components_, noise_variance=f.noise_variance_)


def test_sparse_with_every_component_a_candidate_is_the_exact_em():
    """K = M candidates: the same EM as the exact E-step (float32 products: equal to ~1e-5)."""
    X, _ = _mixture()
    start = _start(X, 6, 3)
    kw = dict(n_init=1, max_iter=8, tol=0.0, init_params=start)
    exact = MPPCA(6, 3, e_step="exact", **kw).fit(X)
    sparse = MPPCA(6, 3, e_step="sparse", n_candidates=6, resp_threshold=1e6, **kw).fit(X)
    lb_e, lb_s = np.asarray(exact.lower_bounds_), np.asarray(sparse.lower_bounds_)
    assert np.ptp(lb_e) > 0.1  # EM moved
    np.testing.assert_allclose(lb_s, lb_e, rtol=1e-5)
    np.testing.assert_allclose(sparse.weights_, exact.weights_, atol=1e-5)
    np.testing.assert_allclose(sparse.means_, exact.means_, atol=1e-4 * np.abs(exact.means_).max())
    np.testing.assert_allclose(sparse.noise_variance_, exact.noise_variance_, rtol=1e-4)
    np.testing.assert_allclose(np.abs(sparse.components_), np.abs(exact.components_),
                               atol=1e-4 * np.abs(exact.components_).max())


def test_sparse_with_two_candidates_reaches_the_exact_optimum_on_separated_clusters():
    """K = 2 of M = 6: after 60 iterations from the same k-means start, the same log-likelihood (to 1e-3) and
    partition; the bounds rise (up to float32 rounding) although the gate runs only every 3rd iteration."""
    X, _ = _mixture(seed=1, sep=1.0)
    kw = dict(n_init=1, max_iter=60, tol=0.0, random_state=0)  # the same k-means start
    exact = MPPCA(6, 3, e_step="exact", **kw).fit(X)
    sparse = MPPCA(6, 3, e_step="sparse", n_candidates=2, gate_refresh=3, **kw).fit(X)
    assert exact.lower_bounds_[-1] - exact.initial_bound_ > 10.0  # EM moved a long way
    assert sparse.lower_bound_ == pytest.approx(exact.lower_bound_, rel=1e-3)
    assert np.all(np.diff(sparse.lower_bounds_) > -1e-6 * abs(sparse.lower_bound_))
    assert np.array_equal(sparse.predict(X), exact.predict(X))
    np.testing.assert_allclose(sparse.means_, exact.means_, atol=1e-3 * np.abs(exact.means_).max())


def test_threshold_drops_far_components_but_keeps_the_fit():
    """A small responsibility threshold (2 nats) changes the fit only slightly on separated clusters."""
    X, _ = _mixture(seed=2)
    start = _start(X, 6, 3, seed=5)
    kw = dict(n_init=1, max_iter=30, tol=0.0, init_params=start, e_step="sparse", n_candidates=3)
    loose = MPPCA(6, 3, resp_threshold=1e6, **kw).fit(X)
    tight = MPPCA(6, 3, resp_threshold=2.0, **kw).fit(X)
    assert tight.lower_bound_ == pytest.approx(loose.lower_bound_, rel=1e-3)


def test_auto_e_step_is_exact_below_and_sparse_from_the_threshold():
    assert MPPCA(SPARSE_MIN_COMPONENTS - 1)._sparse_setup() is None
    assert MPPCA(SPARSE_MIN_COMPONENTS)._sparse_setup() is not None
    assert MPPCA(3, e_step="sparse", n_candidates=2)._sparse_setup().n_candidates == 2
    # many rows: sparse from fewer components on, never below that
    k = SPARSE_MIN_COMPONENTS_LARGE_N
    assert MPPCA(k)._sparse_setup(SPARSE_MIN_ROWS) is not None and MPPCA(k)._sparse_setup(SPARSE_MIN_ROWS - 1) is None
    assert MPPCA(k - 1)._sparse_setup(10 * SPARSE_MIN_ROWS) is None
    assert MPPCA(k, e_step="exact")._sparse_setup(SPARSE_MIN_ROWS) is None
    with pytest.raises(ValueError, match="e_step"):
        MPPCA(3, 2, e_step="fast").fit(np.random.default_rng(0).standard_normal((20, 4)))


def test_sparse_stream_over_array_shards_equals_in_memory_fit():
    """fit_stream over uneven shards = fit (same start), the sparse E-step's per-shard candidates included (float32
    products over differently sized blocks round differently: equal to ~1e-6)."""
    X, _ = _mixture(n=900, seed=6)
    start = _start(X, 6, 3, seed=6)
    kw = dict(n_init=1, max_iter=10, tol=0.0, init_params=start, e_step="sparse", n_candidates=2, gate_refresh=4)
    ref = MPPCA(6, 3, **kw).fit(X)
    got = MPPCA(6, 3, **kw).fit_stream(np.array_split(X, 5))
    assert np.ptp(ref.lower_bounds_) > 1.0
    np.testing.assert_allclose(got.lower_bounds_, ref.lower_bounds_, rtol=2e-6)
    np.testing.assert_allclose(got.means_, ref.means_, atol=1e-5 * np.abs(ref.means_).max())


# ----------------------------------------------------------------------------- Ray


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return write_synthetic_dataset(tmp_path_factory.mktemp("data") / "sharded", (30, 25, 30, 15), 16)


@pytest.mark.ray
def test_sparse_ray_fit_equals_local_fit(dataset, local_ray):
    """The sparse E-step on 2 local Ray workers gives the local streaming fit (results summed in shard order)."""
    layout = ShapeStructureModel(3, 4, structure_weight=10.0, max_iter=1, n_init=1, random_state=0
                                 ).fit_stream(dataset, "train").layout_
    kw = dict(n_init=1, max_iter=10, tol=0.0, random_state=3, init="random", e_step="sparse", n_candidates=2,
              gate_refresh=3)
    fits = {}
    for executor in ("local", "ray"):
        src = streaming.DatasetShards.open(dataset, "train", executor=executor, workers=2).with_layout(layout)
        fits[executor] = MPPCA(3, 4, **kw).fit_stream(src, init_rows=100)
    a, b = fits["local"], fits["ray"]
    assert np.ptp(a.lower_bounds_) > 1e-3
    np.testing.assert_allclose(b.lower_bounds_, a.lower_bounds_, rtol=1e-9)
    np.testing.assert_allclose(b.means_, a.means_, rtol=1e-7, atol=1e-9 * np.abs(a.means_).max())
    np.testing.assert_allclose(b.components_, a.components_, rtol=1e-6, atol=1e-8 * np.abs(a.components_).max())


def test_auto_e_step_of_a_fit_follows_its_row_count():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((SPARSE_MIN_ROWS, 3))
    kw = dict(n_init=1, max_iter=1, random_state=0)
    assert MPPCA(SPARSE_MIN_COMPONENTS_LARGE_N, 1, **kw).fit(X).e_step_ == "sparse"
    assert MPPCA(SPARSE_MIN_COMPONENTS_LARGE_N, 1, **kw).fit(X[:-1]).e_step_ == "exact"
