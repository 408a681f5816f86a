"""MPPCA EM at the `motions` scale: N 100,000, d 1657, M 200, streamed from shard files.

Section ``em_scale`` of ``python -m benchmarks.run``. Synthetic data (a mixture of M rank-q Gaussians,
``benchmarks.em.synthetic_mixture``'s recipe, drawn shard by shard so that no process holds all rows)
are written as float32 ``.npy`` shards to a temporary directory; ``MPPCA.fit_stream`` then reads one
shard per task, as the Parquet streaming fit does. Measured: the total fit time (initialisation and
every EM pass), time per EM iteration (median, and the gate iterations apart), peak RSS of the process
during the fit, iterations, the held-out mean log-likelihood against the generating parameters'.
The sparse E-step (``MPPCA(e_step="sparse")``, the default from M 64 on) is what makes this scale fit;
``compare_shards`` > 0 also times the exact E-step on that many shards, extrapolated to N rows, for the
ratio. Wall-clock on a shared machine.
"""

from __future__ import annotations

import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from silpose.model import MPPCA
from silpose.model.shards import ShardSource

from .em import RssSampler, mixture_parameters, mixture_with, result_row


class NpyShards(ShardSource):
    """Shards stored as ``.npy`` files, loaded one at a time per pass (float64 blocks, minus an offset)."""

    def __init__(self, paths, counts, d, rows=None, offset=None):
        self.paths, self.counts, self.n_features = list(paths), list(counts), int(d)
        self.rows = list(rows) if rows is not None else [None] * len(self.paths)
        self.offset = offset

    def _clone(self, rows, offset):
        return NpyShards(self.paths, self.counts, self.n_features, rows, offset)

    def shard_rows(self):
        return [c if r is None else len(r) for c, r in zip(self.counts, self.rows)]

    def map(self, fn, *args, each=None):
        for s, n in enumerate(self.shard_rows()):
            if n:
                X = np.load(self.paths[s], allow_pickle=False).astype(np.float64)
                if self.rows[s] is not None:
                    X = X[self.rows[s]]
                if self.offset is not None:
                    X -= self.offset
                yield fn(X, *(each[s] if each is not None else ()), *args)

    def centred(self, offset):
        base = 0.0 if self.offset is None else self.offset
        return self._clone(self.rows, base + np.asarray(offset, dtype=np.float64))

    def select(self, rows):
        cur = [np.asarray(r) if c is None else c[np.asarray(r)] for c, r in zip(self.rows, rows)]
        return self._clone(cur, self.offset)


def write_synthetic_shards(root: Path, n: int, d: int, q: int, m: int, shard_rows: int, seed: int = 0,
                           noise: float = 0.05, mean_scale: float = 0.25):
    """Draw n rows of a random mixture (``benchmarks.em.synthetic_mixture``'s parameters) into float32
    shards of ``shard_rows`` rows. Returns (paths, counts, truth MPPCA)."""
    rng = np.random.default_rng(seed)
    weights, means, comps, s2 = mixture_parameters(rng, d, q, m, noise, mean_scale)
    paths, counts = [], []
    for k, start in enumerate(range(0, n, shard_rows)):
        rows = min(shard_rows, n - start)
        labels = rng.choice(m, size=rows, p=weights)
        Z = rng.standard_normal((rows, q))
        X = means[labels]
        for i in np.unique(labels):
            sel = labels == i
            X[sel] += Z[sel] @ comps[i].T
        X += np.sqrt(s2[labels])[:, None] * rng.standard_normal((rows, d))
        path = root / f"shard-{k:04d}.npy"
        np.save(path, X.astype(np.float32), allow_pickle=False)
        paths.append(path)
        counts.append(rows)
    return paths, counts, mixture_with(weights, means, comps, s2)


def run(n=100_000, d=1657, q=40, m=200, shard_rows=4000, n_test=2000, max_iter=25, tol=1e-3, init_rows=20_000,
        n_candidates=4, gate_refresh=10, compare_shards=2, seed=0, data_dir=None) -> list[dict]:
    """Fit MPPCA(m, q) by ``fit_stream`` on n synthetic rows in shard files; rows as in ``benchmarks.em``.
    ``data_dir``: write the shards there (kept) instead of a temporary directory; progress goes to stderr."""
    tag = f"EM stream N={n} d={d} q={q} M={m}"
    with tempfile.TemporaryDirectory(prefix="silpose-em-scale-") as tmp:
        t_gen = time.perf_counter()
        paths, counts, truth = write_synthetic_shards(Path(data_dir or tmp), n + n_test, d, q, m, shard_rows, seed)
        t_gen = time.perf_counter() - t_gen
        print(f"em_scale: wrote {len(paths)} shards in {t_gen:.0f} s", file=sys.stderr, flush=True)
        test = np.load(paths[-1], allow_pickle=False).astype(np.float64)[-n_test:]
        counts[-1] -= n_test  # the last n_test rows are held out
        train = NpyShards(paths, counts, d)
        train.rows[-1] = np.arange(counts[-1])
        stamps: list[tuple[float, float]] = []

        def progress(it, lb):
            stamps.append((time.perf_counter(), lb))
            print(f"em_scale: iteration {it} at {stamps[-1][0] - t0:.0f} s wall, {time.process_time() - c0:.0f} s CPU, "
                  f"mean log-likelihood {lb:.3f}", file=sys.stderr, flush=True)

        est = MPPCA(m, q, n_init=1, max_iter=max_iter, tol=tol, random_state=seed, e_step="sparse",
                    n_candidates=n_candidates, gate_refresh=gate_refresh, callback=progress)
        with RssSampler() as rss, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0, c0 = time.perf_counter(), time.process_time()
            est.fit_stream(train, init_rows=init_rows)
            t_fit, c_fit = time.perf_counter() - t0, time.process_time() - c0
        t_iters = np.diff([t0] + [s for s, _ in stamps])
        t_init = float(t_iters[0])  # moments pass, k-means + PPCA start, first pass, first iteration
        per_iter = float(np.median(t_iters[1:])) if len(t_iters) > 1 else float("nan")
        ll_fit, ll_true = est.score(test), truth.score(test)
        rows = [
            result_row(tag, "full streaming fit (sparse E-step)", t_fit, "s", None, None,
                 f"{est.n_iter_} EM iterations (max_iter {max_iter}, tol {tol}, converged {est.converged_}); "
                 f"init_rows {init_rows}, shards of {shard_rows} rows read per pass; K {n_candidates} candidates, "
                 f"gate every {gate_refresh} iterations"),
            result_row(tag, "CPU time of the fit (all threads)", c_fit, "s", None, None,
                 "process user + system time: on an otherwise idle machine the wall time lies between this / "
                 "n_cores and this"),
            result_row(tag, "time per EM iteration (sparse E-step, median)", per_iter, "s", None, None,
                 f"max {float(np.max(t_iters[1:])) if len(t_iters) > 1 else float('nan'):.3g} s (the gate "
                 f"iterations); start + first iteration {t_init:.3g} s"),
            result_row(tag, "peak RSS during the fit", rss.peak / 2**30, "GiB", None, None,
                 f"process total; before the fit {rss.baseline / 2**30:.2f} GiB"),
            result_row(tag, "held-out mean log-likelihood", ll_fit, "nats/sample", ll_true, None,
                 "reference = the generating parameters"),
        ]
        if compare_shards > 0:  # the exact E-step on the first shards only, extrapolated to n rows
            sub = NpyShards(paths[:compare_shards], counts[:compare_shards], d)
            n_sub = int(sum(counts[:compare_shards]))
            exact = MPPCA(m, q, n_init=1, max_iter=1, tol=0.0, e_step="exact",
                          init_params=dict(weights=est.weights_, means=est.means_, components=est.components_,
                                           noise_variance=est.noise_variance_))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t0 = time.perf_counter()
                exact.fit_stream(sub)
                t_exact = (time.perf_counter() - t0) / 2 * n / n_sub  # two exact passes (start, iteration 1)
            rows.append(result_row(tag, "time per EM iteration, exact E-step (float64, all M components)", t_exact, "s",
                             t_exact, t_exact / per_iter, f"extrapolated from {n_sub} rows (one fit_stream of 1 "
                             "iteration = 2 passes); ratio = exact / sparse median iteration"))
    return rows
