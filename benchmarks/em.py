"""MPPCA EM: time per iteration and full fit, against sklearn's GaussianMixture and the BLAS floor.

Section ``em`` of ``python -m benchmarks.run`` (paper scale by default: N 20,000, d 1657, q 30, M 5).

References measured in the same process: ``sklearn.mixture.GaussianMixture(covariance_type="full")``
on the same data, run for ``gmm_iters`` iterations (its per-iteration time is read from its own
verbose output; iteration 1 includes its initialisation, so the last iteration is the pure one),
and the BLAS floor of one EM iteration at these shapes (:func:`benchmarks.blas_floor.em_iteration`:
the products X W and X^T (R Z) every exact EM iteration needs).
Synthetic data: a mixture of M low-rank Gaussians (rank q, decaying spectrum) plus isotropic noise.
Timings are wall-clock on a shared machine; each row says what it measured.
"""

from __future__ import annotations

import contextlib
import io
import re
import threading
import time
import tracemalloc
import warnings

import numpy as np

from silpose.model import MPPCA

from . import blas_floor


def synthetic_mixture(n: int, d: int, q: int, m: int, seed: int = 0, noise: float = 0.05, mean_scale: float = 0.25):
    """Draw n rows from a random mixture of m rank-q Gaussians in d dims plus noise.

    Returns (X (n, d), labels (n,), truth) where truth is an :class:`MPPCA` holding the generating
    parameters (weights_ (m,), means_ (m, d), components_ (m, d, q), noise_variance_ (m,)), so
    ``truth.score(X)`` is the data's mean log-likelihood under them. Component means are N(0, mean_scale^2) per dim
    (0.25: mean separations ~0.35 sqrt(d), 14 at d = 1657, against within-component standard
    deviations <= 3, so k-means finds the clusters; at 0.1 the components overlap and one k-means
    start lands in a far worse optimum); each W is an orthonormal d x q basis times
    singular values decaying from 3 to 0.5.
    """
    rng = np.random.default_rng(seed)
    weights, means, comps, s2 = mixture_parameters(rng, d, q, m, noise, mean_scale)
    labels = rng.choice(m, size=n, p=weights)
    X = np.empty((n, d))
    for i in range(m):
        sel = np.flatnonzero(labels == i)
        X[sel] = means[i] + rng.standard_normal((sel.size, q)) @ comps[i].T
    X += np.sqrt(s2[labels])[:, None] * rng.standard_normal((n, d))
    return X, labels, mixture_with(weights, means, comps, s2)


def mixture_parameters(rng: np.random.Generator, d: int, q: int, m: int, noise: float, mean_scale: float):
    """Random mixture parameters as :func:`synthetic_mixture` describes them: weights (m,) ~ Dirichlet(5),
    means (m, d) ~ N(0, mean_scale^2), components (m, d, q) orthonormal bases times singular values 3 -> 0.5,
    noise variances (m,) uniform in noise x [0.5, 1.5]."""
    weights = rng.dirichlet(np.full(m, 5.0))
    means = mean_scale * rng.standard_normal((m, d))
    comps = np.empty((m, d, q))
    for i in range(m):
        U, _ = np.linalg.qr(rng.standard_normal((d, q)))
        comps[i] = U * np.linspace(3.0, 0.5, q)
    s2 = noise * rng.uniform(0.5, 1.5, m)
    return weights, means, comps, s2


def mixture_with(weights: np.ndarray, means: np.ndarray, components: np.ndarray, noise_variance: np.ndarray) -> MPPCA:
    """An :class:`MPPCA` set to the given parameters (fitted attributes set directly, no EM):
    weights (M,), means (M, d), components (M, d, q), noise_variance (M,)."""
    m, d, q = components.shape
    mix = MPPCA(n_components=m, n_latent=q)
    mix.weights_, mix.means_, mix.components_, mix.noise_variance_ = weights, means, components, noise_variance
    mix.n_features_in_ = d
    return mix


class RssSampler:
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


def result_row(bench, quantity, value, unit, reference=None, ratio=None, note="", **extra):
    return dict(bench=bench, quantity=quantity, value=value, unit=unit, reference=reference, ratio=ratio,
                **extra, note=note)


def run(n=20000, d=1657, q=30, m=5, gmm_iters=2, n_init=3, iter_runs=9, floor_repeats=3, seed=0) -> list[dict]:
    """Time MPPCA EM (per iteration and full fit, peak memory, held-out log-likelihood), the
    full-covariance GaussianMixture on the same data and the BLAS floor of one iteration.

    Rows: bench, quantity, value, unit, reference (GaussianMixture's figure), ratio (reference / value:
    how many times faster MPPCA is), note; the iteration row adds blas_floor_s, over_floor (value /
    blas_floor_s) and floor_products.
    """
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
    with RssSampler() as rss, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        est.fit(X_train)
        t_fit = time.perf_counter() - t0
    _, traced_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    ll_true = truth.score(X_test)
    ll_mppca, n_iter = est.score(X_test), est.n_iter_

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
        del gmm
    del X_train, X_test, est
    floor = blas_floor.floor_columns(t_iter, blas_floor.em_iteration(n, d, m, q), floor_repeats)
    tag = f"EM N={n} d={d} q={q} M={m}"
    return [
        result_row(tag, "time per EM iteration", t_iter, "s", gmm_iter, gmm_iter / t_iter,
             f"median of {iter_runs - 1} iterations (E+M step), min {t_iter_min:.3g} s (ratio "
             f"{gmm_iter / t_iter_min:.3g}); reference = GaussianMixture(full), its last timed iteration",
             **floor),
        result_row(tag, f"full fit (n_init={n_init}, {n_iter} iters best run)", t_fit, "s", t_gmm, None,
             f"reference = GaussianMixture(full) with only max_iter={gmm_iters} incl. its k-means init"),
        result_row(tag, "held-out mean log-likelihood", ll_mppca, "nats/sample", ll_gmm, None,
             f"reference stopped after {gmm_iters} iterations; generating parameters give {ll_true:.4g}"),
        result_row(tag, "peak RSS during MPPCA fit", rss.peak / 2**30, "GiB", None, None,
             f"process total; baseline before fit {rss.baseline / 2**30:.2f} GiB (includes the data)"),
        result_row(tag, "peak traced numpy/Python memory during fit", traced_peak / 2**30, "GiB", None, None,
             "tracemalloc; includes nothing allocated before the fit"),
    ]
