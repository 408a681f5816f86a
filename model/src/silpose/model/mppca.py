"""Mixture of probabilistic principal component analysers (MPPCA), fitted by EM.

Tipping & Bishop (1999), "Mixtures of probabilistic principal component analysers", Neural
Computation 11(2):443-482. Component i models x ~ N(mu_i, C_i) with C_i = W_i W_i^T + sigma_i^2 I,
W_i (d, q). The E-step and M-step cost O(N d q) per component through the q x q matrix
M_i = W_i^T W_i + sigma_i^2 I (see ``_ppca``); EM never forms a d x d matrix (only the
closed-form PPCA initialisation does, when d <= 512).

Used by the shape+structure model (paper eq. 3-4) as the prior over multi-view contour + joint
vectors; :mod:`silpose.model.conditioning` does the Bayesian reconstruction of missing blocks.
"""

from __future__ import annotations

import numbers
import warnings
from typing import Sequence

import numpy as np
from scipy.special import logsumexp
from sklearn.base import BaseEstimator, DensityMixin
from sklearn.cluster import KMeans
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils.validation import check_is_fitted, validate_data

from . import _em, _ppca
from .shards import ArrayShards, ShardSource, split_global_rows

_SHORT_RUN = 5  # EM iterations of each of the n_init short runs (em-EM)
_KMEANS_ROWS = 5000  # k-means initialisation is fitted on at most this many random rows
DEFAULT_INIT_ROWS = 5000  # fit_stream: rows of the initialisation subsample
_FIT_BLOCK = 4096  # fit: rows per block of the in-memory EM passes (bounds the per-pass temporaries) ...
_FIT_BLOCK_VALUES = 1 << 21  # ... and fewer when M (q + 1) is large: a block's (rows, M q + M) products stay <= 16 MB
SPARSE_MIN_COMPONENTS = 64  # e_step="auto": the sparse E-step from this many components on
#: e_step="auto": also sparse from this many rows on when M >= SPARSE_MIN_COMPONENTS_LARGE_N. Measured on the
#: motions preset (43,200 rows, d 1,657, M 60, q 40, `silpose train motions`, idle 2-core machine): 3 min 26 s wall,
#: 230 s user CPU, held-out log-likelihood 642.9 / joint error 16.58 cm, against the exact E-step's 906 s user CPU
#: (33 iterations) and 642.0 / 16.54 cm; at 12,000 rows the same held-out figures at 37 vs 88 s CPU.
SPARSE_MIN_ROWS = 20_000
SPARSE_MIN_COMPONENTS_LARGE_N = 32
_SPARSE_ROWS_PER_COMPONENT = 50  # sparse E-step: k-means and the initialisation see >= this many rows per component


def fit_block_rows(n_components: int, n_latent: int) -> int:
    """Rows per block of the in-memory fit: 4,096, or fewer (>= 256) so that a block's E-step products
    (rows x M (q + 1) float64, ``silpose.model._ppca.e_step_products``) hold at most 2^21 values."""
    return int(min(_FIT_BLOCK, max(256, _FIT_BLOCK_VALUES // max(1, n_components * (n_latent + 1)))))


class MPPCA(DensityMixin, BaseEstimator):
    """Mixture of probabilistic PCA, a scikit-learn density estimator.

    Parameters
    ----------
    n_components : int, number of mixture components M (>= 1).
    n_latent : int or None, latent dimension q of every component (1 <= q < n_features); None (the
        default) = min(10, n_features - 1), so the defaults fit any data of two or more features.
    tol : float, EM stops when the mean log-likelihood per sample rises by less than ``tol``.
    max_iter : int, maximum EM iterations of a run (the winning run's short phase included).
    n_init : int, number of initialisations. Each gets a short EM run (5 iterations); the run with
        the best log-likelihood is continued to convergence ("em-EM", Biernacki et al. 2003). With
        n_init = 1 the single run goes straight to convergence.
    init : {"kmeans", "random"}, hard assignment used to start each run: one k-means run
        (sklearn ``KMeans`` on at most 5000 random rows, then every row to its nearest centre) or
        random data points as centres; each cluster then gets its closed-form PPCA (T&B 1999
        PPCA, eqs. 7-8).
    reg_variance : float, floor on every noise variance sigma_i^2, relative to the mean
        per-feature variance of the training data.
    init_params : None or dict with ``weights`` (M,), ``means`` (M, d), ``components`` (M, d, q) and
        ``noise_variance`` (M,): start EM from these parameters (data coordinates) instead of
        ``init``; needs n_init = 1. Used to compare fits on the same initialisation.
    noise_dof : bool, after EM multiply each component's noise variance by n_i / (n_i - 1 - q), the
        degrees of freedom its mean and subspace used (:func:`silpose.model._ppca.dof_noise_factor`): the
        maximum-likelihood sigma_i^2 is the residual left by a q-dimensional subspace fitted to the same
        n_i rows, biased low by (n_i - 1 - q) / n_i, which makes every training row far likelier under
        its own component than a new row (train vs held-out log-likelihood). EM itself stays maximum
        likelihood.
    random_state : None, int or numpy Generator; every random draw comes from
        ``numpy.random.default_rng(random_state)``.
    callback : callable(iteration: int, lower_bound: float) or None, called after each EM
        iteration (the CLI turns it into a progress display). With n_init > 1 the count restarts
        at 1 for each short run, then the winning run continues from its own count.
    verbose : int, 0 silent, 1 prints one line per initialisation, 2 one per iteration.
    e_step : {"auto", "exact", "sparse"}, how the E-step scores the rows. "exact" computes every row's
        log density under every component in float64 (O(N d M q) per iteration). "sparse" (for M in the
        hundreds; ``silpose.model._em.SparseEStep``) scores each row under ``n_candidates`` components
        only: the top ones of a float32 gate over all M components, run at the first iteration and
        every ``gate_refresh`` iterations (and before convergence is declared), kept in between;
        within them, components more than ``resp_threshold`` nats below the row's best get no
        responsibility; per-candidate products in float32, log densities and sums in float64. Its
        log-likelihoods are lower bounds (the candidates' terms only). The sparse mode also gives
        k-means and the initialisation at least 50 rows per component. "auto" = "sparse" from
        ``SPARSE_MIN_COMPONENTS`` (64) components on, or from ``SPARSE_MIN_COMPONENTS_LARGE_N`` (32) on
        with at least ``SPARSE_MIN_ROWS`` (20,000) rows to fit, else "exact".
    n_candidates, resp_threshold, gate_refresh : the sparse E-step's settings (above).

    Fitted attributes
    -----------------
    e_step_ "exact" or "sparse" (what ``e_step`` resolved to),
    weights_ (M,), means_ (M, d), components_ (M, d, q) the W matrices, noise_variance_ (M,),
    converged_ (bool), n_iter_ (int, EM iterations of the winning run), lower_bound_ (float, mean
    log-likelihood per sample of the training data under the final parameters, after the noise_dof
    correction when on), lower_bounds_ (list of n_iter_ floats, the same after each EM iteration of
    the winning run before any correction, non-decreasing), initial_bound_ (float, the same under the
    winning run's starting parameters; ``lower_bounds_[-1] - initial_bound_`` is what EM gained),
    noise_dof_factor_ ((M,) factors applied to the noise variances, ones when noise_dof is off),
    n_underdetermined_ (components with n_i <= q + 1 rows, whose noise variance cannot be estimated:
    they get the largest corrected variance of the others), n_features_in_, n_fit_samples_.

    ``fit(X)`` holds X in memory; ``fit_stream(shards)`` reads one shard at a time (out of core,
    optionally on Ray). Both run the same E-step/M-step code (``silpose.model._em``).
    """

    def __init__(self, n_components=5, n_latent=None, *, tol=1e-4, max_iter=200, n_init=3, init="kmeans",
                 reg_variance=1e-6, init_params=None, noise_dof=False, random_state=None, callback=None, verbose=0,
                 e_step="auto", n_candidates=4, resp_threshold=30.0, gate_refresh=10):
        self.n_components = n_components
        self.n_latent = n_latent
        self.tol = tol
        self.max_iter = max_iter
        self.n_init = n_init
        self.init = init
        self.reg_variance = reg_variance
        self.init_params = init_params
        self.noise_dof = noise_dof
        self.random_state = random_state
        self.callback = callback
        self.verbose = verbose
        self.e_step = e_step
        self.n_candidates = n_candidates
        self.resp_threshold = resp_threshold
        self.gate_refresh = gate_refresh

    # ------------------------------------------------------------------ validation
    def _check_params(self, n_samples: int, n_features: int) -> None:
        def _int(name, lo):
            v = getattr(self, name)
            if not isinstance(v, numbers.Integral) or isinstance(v, bool) or v < lo:
                raise ValueError(f"MPPCA: {name} must be an integer >= {lo}, got {v!r}")

        _int("n_components", 1)
        if self.n_latent is not None:
            _int("n_latent", 1)
        _int("max_iter", 1)
        _int("n_init", 1)
        for name in ("tol", "reg_variance"):
            v = getattr(self, name)
            if not isinstance(v, numbers.Real) or not np.isfinite(v) or v < 0:
                raise ValueError(f"MPPCA: {name} must be a finite number >= 0, got {v!r}")
        if self.e_step not in ("auto", "exact", "sparse"):
            raise ValueError(f"MPPCA: e_step must be 'auto', 'exact' or 'sparse', got {self.e_step!r}")
        _int("n_candidates", 1)
        _int("gate_refresh", 1)
        v = self.resp_threshold
        if not isinstance(v, numbers.Real) or not v > 0:
            raise ValueError(f"MPPCA: resp_threshold must be a number > 0, got {v!r}")
        if self.init not in ("kmeans", "random"):
            raise ValueError(f"MPPCA: init must be 'kmeans' or 'random', got {self.init!r}")
        if self.callback is not None and not callable(self.callback):
            raise ValueError("MPPCA: callback must be callable(iteration, lower_bound) or None")
        if n_samples < max(2, self.n_components):
            raise ValueError(f"MPPCA: n_samples = {n_samples} but at least max(2, n_components = "
                             f"{self.n_components}) samples are needed")
        if self.n_latent is None and n_features < 2:
            raise ValueError(f"MPPCA: n_features = {n_features}, but a mixture of PPCA needs at least 2 features "
                             "(a latent dimension 1 <= q < n_features)")
        if self.n_latent is not None and self.n_latent >= n_features:
            raise ValueError(f"MPPCA: n_latent = {self.n_latent} must be smaller than n_features = "
                             f"{n_features}")

    def _sparse_setup(self, n_rows: int | None = None) -> "_em.SparseEStep | None":
        """The sparse E-step's settings when ``e_step`` resolves to "sparse" for a fit on ``n_rows`` rows (None:
        unknown), else None (exact)."""
        m = int(self.n_components)
        large = n_rows is not None and n_rows >= SPARSE_MIN_ROWS and m >= SPARSE_MIN_COMPONENTS_LARGE_N
        sparse = self.e_step == "sparse" or (self.e_step == "auto" and (m >= SPARSE_MIN_COMPONENTS or large))
        return _em.SparseEStep(int(self.n_candidates), float(self.resp_threshold), int(self.gate_refresh)) if sparse else None

    def _latent_dim(self, n_features: int) -> int:
        """The latent dimension q a fit on ``n_features`` features uses (``n_latent``, or its default)."""
        return min(10, n_features - 1) if self.n_latent is None else int(self.n_latent)

    # ------------------------------------------------------------------ fitting
    def fit(self, X, y=None) -> "MPPCA":
        """Fit by EM. X (N, d) array-like of finite numbers; y ignored. Returns self.

        The in-memory fit is the streaming EM (``fit_stream``) over X's rows in blocks of 4,096 or fewer
        (:func:`fit_block_rows`; views of X,
        centred block by block in each pass), so besides X only one block's temporaries are held.
        """
        X = validate_data(self, X, dtype=np.float64, ensure_min_samples=1, ensure_min_features=1)
        rows = _FIT_BLOCK if self._sparse_setup(X.shape[0]) else fit_block_rows(int(self.n_components), self._latent_dim(X.shape[1]))
        blocks = [X[i:i + rows] for i in range(0, X.shape[0], rows)]  # views, no copies
        return self._fit_source(ArrayShards(blocks).checked(), init_rows=None)

    def fit_stream(self, shards, init_rows: int = DEFAULT_INIT_ROWS) -> "MPPCA":
        """Fit by EM, reading the data one shard at a time (out of core). Returns self.

        shards: a ``silpose.model.shards.ShardSource`` (e.g. ``silpose.model.streaming.DatasetShards``
            over Parquet files, locally or on Ray) or a sequence of (n_s, d) arrays.
        init_rows: the k-means + per-cluster PPCA initialisation (``init``) is fitted on at most this
            many rows drawn uniformly without replacement across the shards (all rows if there are
            fewer: then the initialisation, and so the fit, equals ``fit`` on the concatenated rows
            up to rounding). Ignored when ``init_params`` is given.

        Every EM iteration is one pass over the shards: each returns its E-step log-likelihood and
        M-step sums (``silpose.model._em``), which are added up in shard order; memory is bounded by
        one shard's features plus O(d M q) sums. Same E-step/M-step code as ``fit``.
        """
        if not isinstance(init_rows, numbers.Integral) or init_rows < max(2, int(self.n_components)):
            raise ValueError(f"MPPCA: init_rows must be an integer >= max(2, n_components), got {init_rows!r}")
        source = shards if isinstance(shards, ShardSource) else ArrayShards(list(shards))
        self.n_features_in_ = int(source.n_features)
        return self._fit_source(source, init_rows=int(init_rows))

    def _fit_source(self, source: ShardSource, init_rows: int | None) -> "MPPCA":
        moments = _em.reduce_sum(source.map(_em.shard_moments))
        n, d = moments.n, moments.mean.shape[0]
        self._check_params(n, d)
        self.n_latent_ = self._latent_dim(d)
        rng = np.random.default_rng(self.random_state)
        offset = moments.mean  # EM runs on x - mean: keeps the expanded ||x - mu||^2 precise
        data_var = moments.m2 / (n * d)  # mean per-feature variance
        var_floor = max(self.reg_variance * data_var if data_var > 0 else self.reg_variance, 1e-300)
        src = source.centred(offset)
        self._sparse = self._sparse_setup(n)
        if self._sparse is not None and init_rows is not None:
            init_rows = max(init_rows, _SPARSE_ROWS_PER_COMPONENT * int(self.n_components))

        # "em-EM" (Biernacki, Celeux & Govaert 2003, "Choosing starting values for the EM algorithm",
        # CSDA 41): n_init short runs from different starts, the best one continued to convergence.
        if self.init_params is not None:
            starts = [self._explicit_start(d).shifted(offset)]
        else:
            # in memory (no row limit) the start reads the rows block by block, never a second copy of X
            X0 = _SourceRows(src) if init_rows is None else _ArrayRows(self._init_rows(src, init_rows, rng))
            starts = [self._initial_params(X0, rng, var_floor) for _ in range(self.n_init)]
            del X0
        runs = [self._start(src, p) for p in starts]
        if len(runs) > 1:
            for k, run in enumerate(runs):
                self._iterate(src, run, min(_SHORT_RUN, self.max_iter), var_floor, k)
        k_best = max(range(len(runs)), key=lambda k: runs[k]["bounds"][-1] if runs[k]["bounds"] else -np.inf)
        best = runs[k_best]
        self._iterate(src, best, self.max_iter, var_floor, k_best)
        del runs
        p = best["params"]
        self.noise_dof_factor_ = np.ones(p.weights.shape[0])
        self.n_underdetermined_ = 0
        self.lower_bound_ = best["bounds"][-1]
        if self.noise_dof:
            factor, under = _ppca.dof_noise_factor(p.weights * n, d, p.components.shape[2])
            s2 = p.noise_variance * factor
            if under.any():
                s2[under] = s2[~under].max() if (~under).any() else max(data_var, var_floor)
            self.noise_dof_factor_ = s2 / p.noise_variance
            self.n_underdetermined_ = int(under.sum())
            p = _em.Params(p.weights, p.means, p.components, s2)
            stats = self._pass(src, best, p)  # the training log-likelihood of the final parameters
            self.lower_bound_ = stats.loglik / stats.n
        self.weights_ = p.weights
        self.means_ = p.means + offset
        self.components_ = p.components
        self.noise_variance_ = p.noise_variance
        self.converged_ = best["converged"]
        self.e_step_ = "exact" if self._sparse is None else "sparse"
        self.n_iter_ = len(best["bounds"])
        self.initial_bound_ = best["initial"]
        self.lower_bounds_ = list(best["bounds"])
        self.n_fit_samples_ = int(n)
        if not self.converged_:
            warnings.warn(f"MPPCA: EM did not converge in max_iter = {self.max_iter} iterations "
                          f"(tol = {self.tol}); try more iterations or a larger tol.", ConvergenceWarning)
        return self

    def _explicit_start(self, d: int) -> _em.Params:
        """``init_params`` validated against (M, d, q), as float64 copies (data coordinates)."""
        m, q = int(self.n_components), self.n_latent_
        if self.n_init != 1:
            raise ValueError(f"MPPCA: init_params gives one start; n_init must be 1, got {self.n_init}")
        p = self.init_params
        shapes = {"weights": (m,), "means": (m, d), "components": (m, d, q), "noise_variance": (m,)}
        if not isinstance(p, dict) or set(p) != set(shapes):
            got = sorted(p) if isinstance(p, dict) else type(p).__name__
            raise ValueError(f"MPPCA: init_params must be a dict with keys {sorted(shapes)}, got {got}")
        arrays = {}
        for key, shape in shapes.items():
            a = np.array(p[key], dtype=np.float64)
            if a.shape != shape:
                raise ValueError(f"MPPCA: init_params[{key!r}] must have shape {shape}, got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"MPPCA: init_params[{key!r}] contains NaN or infinity")
            arrays[key] = a
        if np.any(arrays["weights"] <= 0) or np.any(arrays["noise_variance"] <= 0):
            raise ValueError("MPPCA: init_params weights and noise_variance must be > 0")
        arrays["weights"] /= arrays["weights"].sum()
        return _em.Params(**arrays)

    @staticmethod
    def _init_rows(src: ShardSource, limit: int | None, rng) -> np.ndarray:
        """(n0, d) rows for the initialisation: all rows when ``limit`` is None or not exceeded,
        else ``limit`` rows drawn without replacement across the shards (in shard order)."""
        counts = src.shard_rows()
        total = int(sum(counts))
        if limit is not None and total > limit:
            idx = np.sort(rng.choice(total, size=limit, replace=False))
            src = src.select(split_global_rows(idx, counts))
        parts = list(src.map(_em.take_rows))
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _initial_labels(self, X: "_ArrayRows | _SourceRows", rng) -> np.ndarray:
        """Hard initial assignment (N,): k-means fitted on at most _KMEANS_ROWS random rows (then
        every row goes to its nearest centre), or nearest of M random rows for init="random"."""
        n, m = X.n, self.n_components
        if m == 1:
            return np.zeros(n, dtype=np.intp)
        if self.init == "kmeans":
            k_rows = _KMEANS_ROWS if self._sparse is None else max(_KMEANS_ROWS, _SPARSE_ROWS_PER_COMPONENT * m)
            rows = rng.choice(n, size=k_rows, replace=False) if n > k_rows else np.arange(n)
            km = KMeans(n_clusters=m, n_init=1, random_state=int(rng.integers(2**31 - 1))).fit(X.take(rows))
            centres = km.cluster_centers_
        else:
            centres = X.take(rng.choice(n, size=m, replace=False))
        c2 = np.einsum("ij,ij->i", centres, centres)[None, :]
        # -2 x.c + ||c||^2 (+ ||x||^2, a row constant), block by block
        return np.concatenate([np.argmin(-2.0 * B @ centres.T + c2, axis=1) for B in X.blocks()])

    def _initial_params(self, X: "_ArrayRows | _SourceRows", rng, var_floor) -> _em.Params:
        """One initialisation from the rows X (n0 rows): hard labels, closed-form PPCA per cluster."""
        n, d = X.n, X.d
        m, q = self.n_components, self.n_latent_
        labels = self._initial_labels(X, rng)
        weights = np.empty(m)
        means = np.empty((m, d))
        comps = np.empty((m, d, q))
        s2 = np.empty(m)
        for i in range(m):
            idx = np.flatnonzero(labels == i)
            if idx.size == 0:  # empty cluster: restart it on one random sample
                idx = np.array([rng.integers(n)])
            members = X.take(idx)
            weights[i] = members.shape[0] / n
            means[i], comps[i], s2[i] = _ppca.ppca_closed_form(members, q, var_floor, rng)
            del members
        return _em.Params(weights / weights.sum(), means, comps, s2)

    def _start(self, src: ShardSource, params: _em.Params) -> dict:
        """A run at ``params``: its first pass (E-step log-likelihood and M-step sums)."""
        run = dict(params=params, prev=None, initial=None, bounds=[], converged=False, cand=None, since_gate=0)
        stats = self._pass(src, run, params)
        ll = stats.loglik / stats.n
        run.update(stats=stats, prev=ll, initial=ll)
        return run

    def _pass(self, src: ShardSource, run: dict, params: _em.Params) -> _em.ShardStats:
        """One pass over the shards under ``params``: E-step log-likelihood and M-step sums, added in shard
        order. Sparse E-step: gates when the run has no candidates or ``gate_refresh`` passes used
        them, else scores the run's candidates; updates ``run["cand"]``, ``run["since_gate"]`` and
        ``run["gated"]``."""
        if self._sparse is None:
            return _em.reduce_sum(src.map(_em.shard_stats, params))
        counts = src.shard_rows()
        gate = run["cand"] is None or run["since_gate"] >= self._sparse.refresh
        each = [(None,) if gate else (c,) for c in (run["cand"] or [None] * len(counts))]
        filled = [s for s, n in enumerate(counts) if n]
        total, cands = None, [None] * len(counts)
        for s, (stats, cand) in zip(filled, src.map(_em.shard_stats_sparse, params, self._sparse, each=each)):
            total = stats if total is None else total + stats  # one shard's sums held at a time
            cands[s] = cand
        if total is None:
            raise ValueError("MPPCA: no data (no shard yielded any rows)")
        run.update(cand=cands, since_gate=1 if gate else run["since_gate"] + 1, gated=gate)
        return total

    def _iterate(self, src: ShardSource, run: dict, until: int, var_floor: float, run_idx: int) -> None:
        """Advance one run (dict from ``_start``) in place until ``until`` iterations in total or
        convergence (rise of the mean log-likelihood below tol). An iteration is the M-step from the
        pending sums, then one pass over the shards under the new parameters (their log-likelihood,
        recorded in ``bounds``, and the sums for the next M-step)."""
        while len(run["bounds"]) < until and not run["converged"]:
            it = len(run["bounds"]) + 1
            params = _em.m_step(run["stats"], run["params"], var_floor)  # T&B Appendix C
            stats = self._pass(src, run, params)
            cur = stats.loglik / stats.n
            run.update(params=params, stats=stats)
            run["bounds"].append(cur)
            if self.verbose >= 2:
                print(f"MPPCA run {run_idx} iteration {it}: mean log-likelihood {cur:.6f}")
            if self.callback is not None:
                self.callback(it, cur)
            run["converged"] = abs(cur - run["prev"]) < self.tol
            if run["converged"] and self._sparse is not None and not run["gated"]:
                run["converged"], run["since_gate"] = False, self._sparse.refresh  # gate before stopping
            run["prev"] = cur
        if self.verbose >= 1:
            print(f"MPPCA run {run_idx}: {'converged' if run['converged'] else 'not converged'} after "
                  f"{len(run['bounds'])} iterations, mean log-likelihood {run['prev']:.6f} (N = {run['stats'].n})")

    # ------------------------------------------------------------------ inference
    def _validate_predict(self, X) -> np.ndarray:
        check_is_fitted(self)
        return validate_data(self, X, dtype=np.float64, reset=False)

    def _estimate_weighted_log_prob(self, X) -> np.ndarray:
        return _ppca.weighted_log_prob(X, self.weights_, self.means_, self.components_, self.noise_variance_)

    def score_samples(self, X) -> np.ndarray:
        """Log density log p(x_n) of each row. X (N, d). Returns (N,) in nats."""
        X = self._validate_predict(X)
        return logsumexp(self._estimate_weighted_log_prob(X), axis=1)

    def score(self, X, y=None) -> float:
        """Mean log-likelihood per sample of X (N, d). y ignored."""
        return float(np.mean(self.score_samples(X)))

    def predict_proba(self, X) -> np.ndarray:
        """Posterior component probabilities p(i | x_n). X (N, d). Returns (N, M), rows sum to 1."""
        X = self._validate_predict(X)
        wlp = self._estimate_weighted_log_prob(X)
        return np.exp(wlp - logsumexp(wlp, axis=1)[:, None])

    def predict(self, X) -> np.ndarray:
        """Most probable component of each row. X (N, d). Returns (N,) int."""
        X = self._validate_predict(X)
        return np.argmax(self._estimate_weighted_log_prob(X), axis=1)

    def fit_predict(self, X, y=None) -> np.ndarray:
        """Fit, then return the component labels of X (N,)."""
        return self.fit(X).predict(X)

    def sample(self, n_samples=1, random_state=None):
        """Draw samples from the fitted mixture.

        Returns X (n_samples, d) and labels (n_samples,). Draws come from
        ``numpy.random.default_rng(random_state)`` (or ``self.random_state`` when None):
        label ~ Categorical(weights_), x = mu + W z + sigma eps, z ~ N(0, I_q), eps ~ N(0, I_d).
        """
        check_is_fitted(self)
        if not isinstance(n_samples, numbers.Integral) or n_samples < 1:
            raise ValueError(f"MPPCA.sample: n_samples must be an integer >= 1, got {n_samples!r}")
        rng = np.random.default_rng(self.random_state if random_state is None else random_state)
        m, d, q = self.components_.shape
        counts = rng.multinomial(n_samples, self.weights_)
        labels = np.repeat(np.arange(m), counts)
        z = rng.standard_normal((n_samples, q))
        eps = rng.standard_normal((n_samples, d))
        X = np.empty((n_samples, d))
        for i in range(m):
            sel = labels == i
            X[sel] = self.means_[i] + z[sel] @ self.components_[i].T + np.sqrt(self.noise_variance_[i]) * eps[sel]
        return X, labels

    def n_parameters(self) -> int:
        """Free parameters: (M-1) weights + per component d (mean) + d q - q (q-1)/2 (W up to a
        rotation) + 1 (sigma^2)."""
        check_is_fitted(self)
        m, d, q = self.components_.shape
        return int((m - 1) + m * (d + d * q - q * (q - 1) // 2 + 1))

    def bic(self, X) -> float:
        """Bayesian information criterion on X (N, d): -2 log L + k log N (lower is better)."""
        X = self._validate_predict(X)
        return float(-2.0 * self.score(X) * X.shape[0] + self.n_parameters() * np.log(X.shape[0]))

    def aic(self, X) -> float:
        """Akaike information criterion on X (N, d): -2 log L + 2 k (lower is better)."""
        X = self._validate_predict(X)
        return float(-2.0 * self.score(X) * X.shape[0] + 2 * self.n_parameters())


def pool_mixtures(fits: Sequence["MPPCA"], X: np.ndarray | None = None) -> "MPPCA":
    """One MPPCA whose density is the equal-weight average of the fitted mixtures' densities.

    ``p(x) = (1/F) sum_f p_f(x)`` is again a mixture of PPCA: the F fits' components side by side, each
    weight divided by F (every fit must have the same q and d). Pooling fits from different EM starts
    averages out the start's luck (silpose.model.shape_model, ``n_fits``). Fitted attributes:
    ``weights_``, ``means_``, ``components_``, ``noise_variance_``, ``noise_dof_factor_`` concatenated;
    ``converged_`` all converged; ``n_iter_``, ``lower_bounds_``, ``initial_bound_`` those of the first
    fit; ``runs_`` one dict per fit (``n_iter``, ``initial_bound``, ``final_bound``, ``n_components``);
    ``lower_bound_`` the pooled mixture's mean log-likelihood of ``X`` (N, d) when given, else NaN.
    """
    fits = list(fits)
    if not fits:
        raise ValueError("pool_mixtures: no fitted mixtures given")
    qs = {int(f.components_.shape[2]) for f in fits}
    ds = {int(f.means_.shape[1]) for f in fits}
    if len(qs) != 1 or len(ds) != 1:
        raise ValueError(f"pool_mixtures: the fits differ in latent dimension {sorted(qs)} or features {sorted(ds)}")
    first = fits[0]
    out = MPPCA(n_components=int(sum(f.weights_.shape[0] for f in fits)), n_latent=qs.pop(), tol=first.tol,
                max_iter=first.max_iter, n_init=first.n_init, init=first.init, reg_variance=first.reg_variance,
                noise_dof=first.noise_dof, random_state=first.random_state)
    out.weights_ = np.concatenate([f.weights_ for f in fits]) / len(fits)
    out.means_ = np.concatenate([f.means_ for f in fits])
    out.components_ = np.concatenate([f.components_ for f in fits])
    out.noise_variance_ = np.concatenate([f.noise_variance_ for f in fits])
    out.noise_dof_factor_ = np.concatenate([getattr(f, "noise_dof_factor_", np.ones(f.weights_.shape[0])) for f in fits])
    out.n_underdetermined_ = int(sum(getattr(f, "n_underdetermined_", 0) for f in fits))
    out.n_latent_ = int(out.components_.shape[2])
    out.n_features_in_ = ds.pop()
    out.n_fit_samples_ = int(getattr(first, "n_fit_samples_", -1))
    out.converged_ = all(bool(f.converged_) for f in fits)
    out.n_iter_ = int(first.n_iter_)
    out.lower_bounds_ = list(first.lower_bounds_)
    out.initial_bound_ = float(first.initial_bound_)
    out.runs_ = [{"n_iter": int(f.n_iter_), "initial_bound": float(f.initial_bound_),
                  "final_bound": float(f.lower_bounds_[-1]), "n_components": int(f.weights_.shape[0])} for f in fits]
    if X is None:
        out.lower_bound_ = float("nan")
    else:  # in row blocks: the products are (rows, M q + M)
        rows = fit_block_rows(out.n_components, out.n_latent_)
        out.lower_bound_ = float(np.mean(np.concatenate([out.score_samples(X[i:i + rows])
                                                         for i in range(0, X.shape[0], rows)])))
    return out


class _ArrayRows:
    """The initialisation's rows held as one (n, d) array."""

    def __init__(self, X: np.ndarray):
        self.X, (self.n, self.d) = X, X.shape

    def take(self, idx) -> np.ndarray:
        """Rows ``idx`` (in that order), a copy."""
        return self.X[np.asarray(idx)]

    def blocks(self):
        yield self.X


class _SourceRows:
    """The initialisation's rows read from a ShardSource block by block (the in-memory fit's centred
    blocks), so the start never holds a second copy of the data; ``take`` gathers only the rows asked."""

    def __init__(self, src: ShardSource):
        self.src, self.counts = src, src.shard_rows()
        self.n, self.d = int(sum(self.counts)), int(src.n_features)

    def take(self, idx) -> np.ndarray:
        """Rows ``idx`` (global indices, in that order), a copy."""
        idx = np.asarray(idx, dtype=np.int64)
        order = np.argsort(idx, kind="stable")
        parts = list(self.src.select(split_global_rows(idx[order], self.counts)).map(_em.take_rows))
        rows = parts[0] if len(parts) == 1 else np.concatenate(parts)
        out = np.empty_like(rows)
        out[order] = rows
        return out

    def blocks(self):
        yield from self.src.map(_em.take_rows)


__all__ = ["MPPCA", "pool_mixtures", "fit_block_rows"]
