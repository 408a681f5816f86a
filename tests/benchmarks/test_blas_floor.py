"""The BLAS floor: the products it names have the kernels' shapes, and its timings are sane."""

import math

import numpy as np
import pytest

from benchmarks import blas_floor


def test_em_floor_products_are_the_e_and_m_step_products():
    e, m = blas_floor.em_iteration(n=1000, d=50, m=3, q=4)
    assert (e.m, e.k, e.n) == (1000, 50, 12)  # X (N, d) @ [W_1 .. W_M] (d, M q)
    assert (m.m, m.k, m.n) == (50, 1000, 12)  # X^T (d, N) @ [R_i Z_i] (N, M q)
    assert e.flops == m.flops == 2 * 1000 * 50 * 12


def test_inference_floor_products_are_the_observed_and_output_products():
    obs, out = blas_floor.inference(n=10, d_obs=1600, d_out=1657, m=5, q=30)
    assert (obs.m, obs.k, obs.n) == (10, 1600, 150)
    assert (out.m, out.k, out.n) == (10, 150, 1657)
    assert "(10x1600)@(1600x150)" in str(obs)


def test_inference_floor_shapes_match_the_fused_posterior_products():
    """The floor's shapes are those of the two products silpose.model's posterior evaluates: checked by
    computing the posterior mean of a tiny mixture with exactly those two products and comparing it with
    dense Gaussian conditioning (an independent formula)."""
    rng = np.random.default_rng(0)
    m, d, q, n, s2 = 2, 9, 2, 4, 0.1
    W = rng.normal(size=(m, d, q))
    mu = rng.normal(size=(m, d))
    w = np.array([0.3, 0.7])
    obs = np.arange(6)
    a = rng.normal(size=(n, obs.size))
    p_obs, p_out = blas_floor.inference(n, obs.size, d, m, q)
    # product 1: A (n, d_a) @ [W_a,i] (d_a, M q)
    Wa = np.concatenate([W[i, obs] for i in range(m)], axis=1)
    AW = a @ Wa
    assert AW.shape == (p_obs.m, p_obs.n) and Wa.shape == (p_obs.k, p_obs.n)
    xh, logp = [], []
    for i in range(m):
        K = np.eye(q) + W[i, obs].T @ W[i, obs] / s2
        xh.append(np.linalg.solve(K, (AW[:, i * q:(i + 1) * q] - mu[i, obs] @ W[i, obs]).T).T / s2)
        C = W[i, obs] @ W[i, obs].T + s2 * np.eye(obs.size)
        e = a - mu[i, obs]
        logp.append(np.log(w[i]) - 0.5 * (np.linalg.slogdet(C)[1] + np.einsum("nj,nj->n", e @ np.linalg.inv(C), e)))
    logp = np.array(logp).T
    r = np.exp(logp - logp.max(1, keepdims=True))
    r /= r.sum(1, keepdims=True)
    # product 2: [r_i x_hat_i] (n, M q) @ [W_i^T] (M q, d)
    H = np.concatenate([r[:, [i]] * xh[i] for i in range(m)], axis=1)
    B = np.concatenate([W[i].T for i in range(m)], axis=0)
    assert H.shape == (p_out.m, p_out.k) and B.shape == (p_out.k, p_out.n)
    mean = H @ B + r @ mu
    # dense reference: E[x | a] per component with d x d covariances, mixed by the same responsibilities
    dense = np.zeros((n, d))
    for i in range(m):
        C = W[i] @ W[i].T + np.diag(np.r_[np.full(obs.size, s2), np.zeros(d - obs.size)])
        gain = C[:, obs] @ np.linalg.inv(C[np.ix_(obs, obs)])
        dense += r[:, [i]] * (mu[i] + (a - mu[i, obs]) @ gain.T)
    np.testing.assert_allclose(mean[:, obs.size:], dense[:, obs.size:], rtol=1e-10, atol=1e-12)


def test_time_product_grows_with_the_work_and_floor_columns_are_a_ratio():
    small = blas_floor.Product("small", 20, 20, 20)
    big = blas_floor.Product("big", 300, 300, 300)  # 3,375x the flops
    t_small, t_big = blas_floor.time_product(small, min_seconds=0.01), blas_floor.time_product(big, min_seconds=0.01)
    assert 0 < t_small < t_big
    cols = blas_floor.floor_columns(1.0, (small, big), repeats=2)
    assert cols["blas_floor_s"] > 0
    assert math.isclose(cols["over_floor"], 1.0 / cols["blas_floor_s"], rel_tol=1e-12)
    assert cols["floor_products"] == f"{small} + {big}"


def test_time_product_runs_at_least_repeats_times_and_min_seconds():
    calls = []
    p = blas_floor.Product("tiny", 2, 2, 2)
    real = np.matmul

    def counting(*a, **k):
        calls.append(1)
        return real(*a, **k)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(blas_floor.np, "matmul", counting)
        blas_floor.time_product(p, repeats=5, min_seconds=0.0)
        assert len(calls) == 5
        calls.clear()
        blas_floor.time_product(p, repeats=1, min_seconds=0.02)
        assert len(calls) > 5  # microsecond products are repeated until min_seconds have passed


def test_rows_of_the_same_shapes_share_the_fastest_floor():
    rows = [dict(case="a", seconds=2.0, blas_floor_s=0.5, over_floor=4.0, floor_products="P"),
            dict(case="b", seconds=3.0, blas_floor_s=0.25, over_floor=12.0, floor_products="P"),
            dict(case="c", seconds=1.0, blas_floor_s=0.1, over_floor=10.0, floor_products="Q"),
            dict(case="d", seconds=1.0)]
    out = blas_floor.shared_floor(rows)
    assert [r["blas_floor_s"] for r in out[:3]] == [0.25, 0.25, 0.1]
    assert [r["over_floor"] for r in out[:3]] == [8.0, 12.0, 10.0]  # seconds / the shared floor
    assert "blas_floor_s" not in out[3]
