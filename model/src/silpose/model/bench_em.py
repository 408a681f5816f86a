"""Benchmark: MPPCA EM and conditional inference against dense references, measured in one session.

    python -m silpose.model.bench_em            # paper scale: N=20,000, d=1657, q=30, M=5
    python -m silpose.model.bench_em --quick    # small smoke version

EM reference: ``sklearn.mixture.GaussianMixture(covariance_type="full")`` on the same data, run for
``gmm_iters`` iterations (its per-iteration time is read from its own verbose output; iteration 1
includes its initialisation, so the last iteration is the pure one). Inference reference: dense
Gaussian conditioning (d x d covariance, Cholesky of C_aa) on the same observations.
Synthetic data: a mixture of M low-rank Gaussians (rank q, decaying spectrum) plus isotropic noise.
Timings are wall-clock on a shared machine; each row says what it measured.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import threading
import time
import tracemalloc
import warnings

import numpy as np
from scipy.special import logsumexp

from silpose.model import _ppca
from silpose.model.conditioning import Conditioner, MixtureParams as _Params, condition
from silpose.model.mppca import MPPCA


def synthetic_mixture(n: int, d: int, q: int, m: int, seed: int = 0, noise: float = 0.05, mean_scale: float = 0.25):
    """Draw n rows from a random mixture of m rank-q Gaussians in d dims plus noise.

    Returns (X (n, d), labels (n,), params) where params has weights_ (m,), means_ (m, d),
    components_ (m, d, q) and noise_variance_ (m,). Component means are N(0, mean_scale^2) per dim
    (0.25: mean separations ~0.35 sqrt(d), 14 at d = 1657, against within-component standard
    deviations <= 3, so k-means finds the clusters; at 0.1 the components overlap and one k-means
    start lands in a far worse optimum); each W is an orthonormal d x q basis times
    singular values decaying from 3 to 0.5.
    """
    rng = np.random.default_rng(seed)
    weights = rng.dirichlet(np.full(m, 5.0))
    means = mean_scale * rng.standard_normal((m, d))
    comps = np.empty((m, d, q))
    for i in range(m):
        U, _ = np.linalg.qr(rng.standard_normal((d, q)))
        comps[i] = U * np.linspace(3.0, 0.5, q)
    s2 = noise * rng.uniform(0.5, 1.5, m)
    labels = rng.choice(m, size=n, p=weights)
    X = np.empty((n, d))
    for i in range(m):
        sel = np.flatnonzero(labels == i)
        X[sel] = means[i] + rng.standard_normal((sel.size, q)) @ comps[i].T
    X += np.sqrt(s2[labels])[:, None] * rng.standard_normal((n, d))
    return X, labels, _Params(weights, means, comps, s2)


class _RssSampler:
    """Peak resident set size (bytes) of this process, sampled every 20 ms in a thread."""

    def __init__(self):
        import psutil

        self._proc = psutil.Process()
        self.peak = self._proc.memory_info().rss
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        while not self._stop.wait(0.02):
            self.peak = max(self.peak, self._proc.memory_info().rss)

    def __enter__(self):
        self.baseline = self._proc.memory_info().rss
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, self._proc.memory_info().rss)


def _row(bench, quantity, value, unit, reference=None, ratio=None, note=""):
    return dict(bench=bench, quantity=quantity, value=value, unit=unit, reference=reference, ratio=ratio, note=note)


def run_em_bench(n=20000, d=1657, q=30, m=5, gmm_iters=2, n_init=3, iter_runs=9, seed=0) -> list[dict]:
    """Time MPPCA EM (per iteration and full fit, peak memory, held-out log-likelihood) and the
    full-covariance GaussianMixture on the same data. Returns table rows (dicts)."""
    X, _, truth = synthetic_mixture(n + n // 4, d, q, m, seed=seed)
    X_train, X_test = X[:n], X[n:]
    del X
    # (a) per-iteration time: one run of a fixed number of iterations (tol=0), callback timestamps
    stamps: list[float] = []
    timed = MPPCA(m, q, n_init=1, max_iter=iter_runs, tol=0.0, random_state=seed,
                  callback=lambda it, lb: stamps.append(time.perf_counter()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        timed.fit(X_train)
    t_iter = float(np.median(np.diff(stamps)))
    t_iter_min = float(np.min(np.diff(stamps)))
    del timed
    # (b) full fit with the defaults (tol=1e-4, max_iter=200) under tracemalloc and an RSS sampler
    est = MPPCA(m, q, n_init=n_init, random_state=seed)
    tracemalloc.start()
    with _RssSampler() as rss, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        est.fit(X_train)
        t_fit = time.perf_counter() - t0
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    ll_true = float(np.mean(logsumexp(_ppca.weighted_log_prob(X_test, truth.weights_, truth.means_,
                                                               truth.components_, truth.noise_variance_), axis=1)))
    ll_mppca = est.score(X_test)

    gmm_iter, t_gmm, ll_gmm = float("nan"), float("nan"), float("nan")
    if gmm_iters > 0:
        from sklearn.mixture import GaussianMixture

        gmm = GaussianMixture(m, covariance_type="full", max_iter=gmm_iters, tol=0.0, random_state=seed,
                              verbose=2, verbose_interval=1)
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            gmm.fit(X_train)
            t_gmm = time.perf_counter() - t0
        lapses = [float(x) for x in re.findall(r"Iteration \d+\s+time lapse ([0-9.]+)s", buf.getvalue())]
        gmm_iter = lapses[-1] if len(lapses) >= 2 else t_gmm / max(gmm_iters, 1)
        ll_gmm = gmm.score(X_test)
    tag = f"EM N={n} d={d} q={q} M={m}"
    return [
        _row(tag, "time per EM iteration", t_iter, "s", gmm_iter, gmm_iter / t_iter,
             f"median of {iter_runs - 1} iterations (E+M step), min {t_iter_min:.3g} s (ratio "
             f"{gmm_iter / t_iter_min:.3g}); reference = GaussianMixture(full), its last timed iteration"),
        _row(tag, f"full fit (n_init={n_init}, {est.n_iter_} iters best run)", t_fit, "s", t_gmm, None,
             f"reference = GaussianMixture(full) with only max_iter={gmm_iters} incl. its k-means init"),
        _row(tag, "held-out mean log-likelihood", ll_mppca, "nats/sample", ll_gmm, None,
             f"reference stopped after {gmm_iters} iterations; generating parameters give {ll_true:.4g}"),
        _row(tag, "peak RSS during MPPCA fit", rss.peak / 2**30, "GiB", None, None,
             f"process total; baseline before fit {rss.baseline / 2**30:.2f} GiB (includes the data)"),
        _row(tag, "peak traced numpy/Python memory during fit", traced_peak / 2**30, "GiB", None, None,
             "tracemalloc; includes nothing allocated before the fit"),
    ]


def _dense_condition(params, X_obs, obs, noise):
    """Reference: dense Gaussian conditioning per component (forms d x d covariances). Returns
    mixture mean (N, d_miss)."""
    d = params.means_.shape[1]
    miss = np.setdiff1d(np.arange(d), obs)
    logp, cm = [], []
    for w, mu, W, s2 in zip(params.weights_, params.means_, params.components_, params.noise_variance_):
        C = W @ W.T + s2 * np.eye(d)
        Caa = C[np.ix_(obs, obs)] + noise * np.eye(obs.size)
        L = np.linalg.cholesky(Caa)
        E = X_obs - mu[obs]
        Y = np.linalg.solve(L, E.T)
        logp.append(np.log(w) - 0.5 * (obs.size * np.log(2 * np.pi) + 2 * np.log(np.diag(L)).sum()
                                       + np.einsum("ij,ij->j", Y, Y)))
        cm.append(mu[miss] + (C[np.ix_(miss, obs)] @ np.linalg.solve(L.T, Y)).T)
    logp = np.array(logp).T
    r = np.exp(logp - logsumexp(logp, axis=1, keepdims=True))
    return np.einsum("nm,mnk->nk", r, np.array(cm))


def run_infer_bench(n=20000, d=1657, q=30, m=5, d_obs=1600, noise=0.01, n_ref=2000, n_single=300,
                    seed=0) -> list[dict]:
    """Conditional-inference throughput (first d_obs dims observed, e.g. 4 views x 200 points x 2,
    the remaining joint dims missing) and single-frame latency, against dense conditioning on the
    same observations. Uses the generating parameters of the synthetic mixture as the model."""
    X, _, params = synthetic_mixture(n, d, q, m, seed=seed)
    obs = np.arange(d_obs)
    X_obs = np.ascontiguousarray(X[:, obs])
    t0 = time.perf_counter()
    res = condition(params, X_obs, obs, noise)
    t_batch = time.perf_counter() - t0
    nr = min(n_ref, n)
    t0 = time.perf_counter()
    ref_mean = _dense_condition(params, X_obs[:nr], obs, noise)
    t_ref = time.perf_counter() - t0
    err = float(np.max(np.abs(ref_mean - res.mean[:nr])))
    prepared = Conditioner(params, obs, noise)
    lat_full, lat_prep = [], []
    for k in range(n_single):
        row = X_obs[k % n : k % n + 1]
        t0 = time.perf_counter()
        condition(params, row, obs, noise)
        t1 = time.perf_counter()
        prepared(row)
        t2 = time.perf_counter()
        lat_full.append(t1 - t0)
        lat_prep.append(t2 - t1)
    tag = f"infer N={n} d={d} d_obs={d_obs} q={q} M={m}"
    fps, fps_ref = n / t_batch, nr / t_ref
    return [
        _row(tag, "batched throughput", fps, "frames/s", fps_ref, fps / fps_ref,
             f"reference = dense d x d conditioning on {nr} frames; max |mean diff| {err:.2e}"),
        _row(tag, "single frame latency, condition()", 1e3 * float(np.median(lat_full)), "ms", None, None,
             f"median of {n_single}, includes the q x q factorisations"),
        _row(tag, "single frame latency, prepared Conditioner", 1e3 * float(np.median(lat_prep)), "ms", None, None,
             f"median of {n_single}"),
    ]


def format_table(rows: list[dict]) -> str:
    """Plain-text table of benchmark rows."""
    def f(v):
        if v is None:
            return "-"
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    head = ["bench", "quantity", "value", "unit", "reference", "ratio", "note"]
    cells = [head] + [[f(r[h]) for h in head] for r in rows]
    widths = [max(len(c[j]) for c in cells) for j in range(len(head))]
    return "\n".join("  ".join(c[j].ljust(widths[j]) for j in range(len(head))) for c in cells)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes (seconds)")
    ap.add_argument("--gmm-iters", type=int, default=2, help="GaussianMixture iterations (0 = skip reference)")
    ap.add_argument("--n-init", type=int, default=3)
    args = ap.parse_args(argv)
    if args.quick:
        size = dict(n=3000, d=257, q=10, m=3)
        rows = run_em_bench(**size, gmm_iters=args.gmm_iters, n_init=args.n_init)
        rows += run_infer_bench(**size, d_obs=200)
    else:
        rows = run_em_bench(gmm_iters=args.gmm_iters, n_init=args.n_init)
        rows += run_infer_bench()
    import os

    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"machine: {os.cpu_count()} cores, load average (1/5/15 min) at the end: {load}")
    print(format_table(rows))


if __name__ == "__main__":
    main()
