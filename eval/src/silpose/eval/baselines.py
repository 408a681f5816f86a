"""Reference methods for E4 (paper §6; docs/conventions.md, "Evaluation protocol"): chance, kNN, ridge and MLP regression.

- **Chance** (:class:`ChanceBaseline`): the paper's "random draw of pose parameters from the
  training set" — each test example gets one training pose drawn uniformly at random, root-
  relative, scored with the same pose error (paper: 29 cm mean).
- **kNN / ridge** (:class:`ViewSubsetRegressor`): regress the 57 root-relative joint coordinates
  (metres) on the observed views' NORMALISED contours (each view ``(n, 2)`` flattened x0, y0, x1,
  ..., views concatenated in rig order) — the same inputs the MPPCA sees. One regressor is fitted
  per view subset on the clean training contours; at test time it gets exactly the noisy contours
  of that subset. kNN: ``sklearn.neighbors.KNeighborsRegressor`` (k = 5, distance-weighted) on float32
  rows (one copy of the subset's training contours); ridge: :class:`silpose.eval.ridge.BlockRidgeCV`, what
  ``sklearn.linear_model.RidgeCV`` fits (the penalty chosen by exact leave-one-out over ``alphas`` on the
  training data only) from normal equations accumulated in row blocks.
  When the MPPCA models joints per stature (``silpose.model.stature``), the regressors get the same
  information: they regress the joints divided by each walker's measured ``stature / 1.75 m`` and
  multiply their prediction by the stature measured from the observed views (``size=``).
- **MLP** (:class:`ViewDropoutMLP`; :func:`fit_mlp`): a discriminative baseline, scikit-learn's
  ``MLPRegressor`` (two hidden layers of 512 ReLU units, Adam) on the same inputs and targets. The
  inputs are centred per feature but scaled by ONE global factor (per-feature standardisation would
  amplify the noise on low-variance contour points); the targets likewise. The caller adds noisy
  copies of the training contours (the eval's noise model) with ``groups`` naming each row's walker;
  the validation split for early stopping is BY GROUP (``GroupShuffleSplit``), so a walker's clean,
  noisy and mirrored copies never straddle it. Training stops when the validation error has not
  improved for ``patience`` epochs; the best epoch's weights are kept. ONE network serves every view
  subset (a per-subset network, as kNN and ridge have, would cost 15 fits for 4 views): its input is
  every rig view's normalised contour, zero for an absent view, plus one presence flag per view (float32,
  built once in training-rows-first order and scaled in place, so the fit holds one copy of its rows), and
  each training row is given a random subset (its size uniform in 1..K), so for a subset it sees the
  same contours the kNN of that subset sees. ``ViewSubsetRegressor(kind="mlp")`` fits one network
  for one subset instead.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import time
import warnings
from dataclasses import dataclass

from sklearn.exceptions import ConvergenceWarning
from sklearn.model_selection import GroupShuffleSplit
from sklearn.neighbors import KNeighborsRegressor
from sklearn.neural_network import MLPRegressor

from silpose.shared.seeds import CHANCE_STREAM, derive_rng
from silpose.shared.skeleton import root_relative

from .ridge import BlockRidgeCV

__all__ = ["ChanceBaseline", "ViewSubsetRegressor", "RIDGE_ALPHAS", "MLPSettings", "GlobalScaledMLP", "fit_mlp",
           "group_split", "masked_features", "ViewDropoutMLP"]

#: Ridge penalties tried by RidgeCV (training-data leave-one-out), normalised contour units.
RIDGE_ALPHAS = tuple(float(a) for a in np.logspace(-3, 3, 13))


class ChanceBaseline:
    """A random training pose per test example.

    Args:
        random_state: seed of the numpy Generator that draws the training indices.

    Fitted attributes: ``poses_`` (N_train, 19, 3) root-relative training joints, metres.
    """

    def __init__(self, random_state: int = 0) -> None:
        self.random_state = random_state

    def fit(self, joints: np.ndarray) -> "ChanceBaseline":
        """Store the root-relative training poses. joints: (N_train, 19, 3) metres."""
        j = np.asarray(joints, dtype=np.float64)
        if j.ndim != 3 or j.shape[1:] != (19, 3) or len(j) == 0:
            raise ValueError(f"joints must have shape (N>0, 19, 3), got {j.shape}")
        self.poses_ = root_relative(j)
        return self

    def draw_indices(self, n: int) -> np.ndarray:
        """(n,) training indices, uniform with replacement, from ``derive_rng(random_state, CHANCE_STREAM)``."""
        rng = derive_rng(self.random_state, CHANCE_STREAM)
        return rng.integers(0, len(self.poses_), size=int(n))

    def predict(self, n: int) -> np.ndarray:
        """(n, 19, 3) random training poses (root-relative, metres)."""
        return self.poses_[self.draw_indices(n)]


def _features(contours_norm: np.ndarray, views: Sequence[int]) -> np.ndarray:
    """(N, |views| n 2) float32: the views' contours of (N, K, n, 2), copied view by view (no float64 temporary);
    float32 contours with every view in order are returned as a reshaped view, not a copy."""
    c = np.asarray(contours_norm)
    if c.ndim != 4 or c.shape[-1] != 2:
        raise ValueError(f"contours_norm must have shape (N, K, n, 2), got {c.shape}")
    bad = [v for v in views if not 0 <= v < c.shape[1]]
    if bad:
        raise ValueError(f"views {bad} not in the input's {c.shape[1]} views")
    if c.dtype == np.float32 and list(views) == list(range(c.shape[1])) and c.flags.c_contiguous:
        return c.reshape(len(c), -1)  # every view: a view of the caller's rows, no copy
    out = np.empty((len(c), len(views)) + c.shape[2:], np.float32)
    for j, v in enumerate(views):
        out[:, j] = c[:, v]
    return out.reshape(len(c), -1)


@dataclass(frozen=True)
class MLPSettings:
    """The MLP baseline's settings: hidden layer sizes, epochs cap, early-stopping patience (epochs),
    validation fraction (of the groups), L2 penalty, mini-batch size, Adam step size, seed."""

    hidden: tuple[int, ...] = (512, 512)
    max_epochs: int = 40
    patience: int = 4
    validation_fraction: float = 0.1
    alpha: float = 1e-4
    batch_size: int = 256
    learning_rate: float = 1e-3
    random_state: int = 0


def group_split(groups: np.ndarray, fraction: float, random_state: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(train rows, validation rows) with about ``fraction`` of the distinct ``groups`` (N,) in validation and
    no group in both (``sklearn.model_selection.GroupShuffleSplit``)."""
    groups = np.asarray(groups)
    if len(np.unique(groups)) < 2:
        raise ValueError("the MLP's validation split needs at least 2 groups (walkers)")
    split = GroupShuffleSplit(n_splits=1, test_size=fraction, random_state=random_state)
    tr, va = next(split.split(np.zeros(len(groups)), groups=groups))
    return np.sort(tr), np.sort(va)


class GlobalScaledMLP:
    """A fitted MLP with its input and output scaling: x -> (x - x_mean) / x_scale, y = y_mean + y_scale * net.

    Attributes: ``net_`` (MLPRegressor), ``x_mean_`` (p,), ``x_scale_`` (float), ``y_mean_`` (t,),
    ``y_scale_`` (float), ``n_epochs_``, ``best_epoch_``, ``val_rmse_`` (validation RMSE, target units,
    of the kept weights), ``train_rows_`` / ``val_rows_`` (row indices of the split), ``fit_time_s_``.
    """

    def predict(self, x: np.ndarray) -> np.ndarray:
        z = ((np.asarray(x, dtype=np.float64) - self.x_mean_) / self.x_scale_).astype(np.float32)
        return self.y_mean_ + self.y_scale_ * self.net_.predict(z).astype(np.float64)


def fit_mlp(x: np.ndarray, y: np.ndarray, groups: np.ndarray, settings: MLPSettings = MLPSettings(), *,
            overwrite_x: bool = False) -> GlobalScaledMLP:
    """Fit the MLP baseline on rows x (N, p), targets y (N, t), walkers ``groups`` (N,): one epoch per
    ``partial_fit`` (float32), early stopping on the group-held-out validation rows. See the module doc.

    The network's inputs are one float32 array, training rows first (a view, no copy per epoch), scaled in
    place: a copy of x, or x itself when ``overwrite_x`` and x is float32 with its training rows first
    (then x is overwritten)."""
    t0 = time.perf_counter()
    y = np.asarray(y, dtype=np.float64)
    if x.ndim != 2 or y.ndim != 2 or len(x) != len(y) or len(groups) != len(x):
        raise ValueError(f"fit_mlp: x (N, p), y (N, t), groups (N,) expected, got {x.shape}, {y.shape}, {np.shape(groups)}")
    out = GlobalScaledMLP()
    out.train_rows_, out.val_rows_ = group_split(groups, settings.validation_fraction, settings.random_state)
    tr, va = out.train_rows_, out.val_rows_
    order = np.concatenate([tr, va])
    n_tr = len(tr)
    in_order = bool(np.array_equal(order, np.arange(len(x))))
    zx = x if overwrite_x and in_order and x.dtype == np.float32 else np.asarray(x, np.float32)[order]
    out.x_mean_, out.x_scale_ = _global_scaling(zx[:n_tr])  # ONE factor for every feature
    for i in range(0, len(zx), _SCALE_BLOCK):
        zx[i:i + _SCALE_BLOCK] -= out.x_mean_.astype(np.float32)
        zx[i:i + _SCALE_BLOCK] /= np.float32(out.x_scale_)
    out.y_mean_ = y[tr].mean(axis=0)
    out.y_scale_ = float(np.sqrt(np.mean((y[tr] - out.y_mean_) ** 2))) or 1.0
    zy = ((y[order] - out.y_mean_) / out.y_scale_).astype(np.float32)
    zx_tr, zy_tr, zx_va, zy_va = zx[:n_tr], zy[:n_tr], zx[n_tr:], zy[n_tr:]
    net = MLPRegressor(hidden_layer_sizes=settings.hidden, alpha=settings.alpha, batch_size=settings.batch_size,
                       learning_rate_init=settings.learning_rate, random_state=settings.random_state, shuffle=True)
    best, best_err, since = None, np.inf, 0
    epoch = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        for epoch in range(1, settings.max_epochs + 1):
            net.partial_fit(zx_tr, zy_tr)
            err = float(np.sqrt(np.mean((net.predict(zx_va) - zy_va) ** 2)))
            if err < best_err:
                best_err, since, out.best_epoch_ = err, 0, epoch
                best = ([w.copy() for w in net.coefs_], [b.copy() for b in net.intercepts_])
            else:
                since += 1
                if since >= settings.patience:
                    break
    net.coefs_, net.intercepts_ = best
    out.net_, out.n_epochs_ = net, epoch
    out.val_rmse_ = best_err * out.y_scale_
    out.fit_time_s_ = time.perf_counter() - t0
    return out


#: rows per block of the in-place input scaling and the float64 sums of :func:`_global_scaling`.
_SCALE_BLOCK = 8192


def _global_scaling(x: np.ndarray) -> tuple[np.ndarray, float]:
    """Per-feature mean (p,) float64 and ONE scale (the root mean square of x - mean over all entries) of
    x (N, p), summed in float64 block by block (no float64 copy of x); scale 1 when x is constant."""
    n = len(x)
    mean = np.zeros(x.shape[1])
    for i in range(0, n, _SCALE_BLOCK):
        mean += x[i:i + _SCALE_BLOCK].sum(axis=0, dtype=np.float64)
    mean /= n
    ss = 0.0
    for i in range(0, n, _SCALE_BLOCK):
        dev = x[i:i + _SCALE_BLOCK] - mean
        ss += float(np.einsum("ij,ij->", dev, dev))
    return mean, float(np.sqrt(ss / (n * x.shape[1]))) or 1.0


def masked_features(contours_norm: np.ndarray, present: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """(N, K n 2 + K) float32: every view's normalised contour (N, K, n, 2), zeros where ``present`` (N, K) is
    False, then the K presence flags (0/1). ``rows``: only these rows, in this order (one gather, no other copy)."""
    c = np.asarray(contours_norm)
    p = np.asarray(present, dtype=bool)
    if c.ndim != 4 or p.shape != c.shape[:2]:
        raise ValueError(f"contours_norm (N, K, n, 2) and present (N, K) expected, got {c.shape} and {p.shape}")
    idx = np.arange(len(c)) if rows is None else np.asarray(rows, dtype=np.intp)
    K, width = c.shape[1], int(np.prod(c.shape[1:]))
    out = np.empty((len(idx), width + K), np.float32)
    for i in range(0, len(idx), _SCALE_BLOCK):
        r = idx[i:i + _SCALE_BLOCK]
        pr = p[r]
        out[i:i + len(r), :width] = np.where(pr[:, :, None, None], c[r], 0.0).reshape(len(r), width)
        out[i:i + len(r), width:] = pr
    return out


class ViewDropoutMLP:
    """The MLP baseline for every view subset at once (module doc): inputs :func:`masked_features`,
    targets root-relative joints (/ size), fitted by :func:`fit_mlp`.

    Fitted attributes: ``estimator_`` (:class:`GlobalScaledMLP`), ``fit_time_s_``, ``n_rows_``.
    """

    def __init__(self, settings: MLPSettings = MLPSettings()) -> None:
        self.settings = settings

    def fit(self, contours_norm: np.ndarray, present: np.ndarray, joints: np.ndarray, groups: np.ndarray,
            size: np.ndarray | None = None) -> "ViewDropoutMLP":
        """contours_norm (N, K, n, 2), present (N, K) bool (the views each row is given), joints (N, 19, 3)
        metres, groups (N,) walker of each row, size optional (N,) stature factors (targets divided by it)."""
        groups = np.asarray(groups)
        tr, va = group_split(groups, self.settings.validation_fraction, self.settings.random_state)
        order = np.concatenate([tr, va])  # the rows as fit_mlp orders them, so it scales x in place
        self.fit_features(masked_features(contours_norm, present, rows=order), np.asarray(joints)[order], groups[order],
                          None if size is None else np.asarray(size)[order])
        self.estimator_.train_rows_, self.estimator_.val_rows_ = tr, va  # in the caller's row numbers
        return self

    def fit_features(self, x: np.ndarray, joints: np.ndarray, groups: np.ndarray,
                     size: np.ndarray | None = None) -> "ViewDropoutMLP":
        """Fit on rows already built by :func:`masked_features`: x (N, K n 2 + K) float32, OVERWRITTEN (scaled in
        place when its rows come training rows first, as ``group_split(groups, ...)`` orders them; else copied);
        joints (N, 19, 3) metres, groups (N,), size optional (N,). Returns self."""
        t0 = time.perf_counter()
        y = root_relative(np.asarray(joints, dtype=np.float64))
        if size is not None:
            y = y / np.asarray(size, dtype=np.float64)[:, None, None]
        self.estimator_ = fit_mlp(x, y.reshape(len(y), -1), np.asarray(groups), self.settings, overwrite_x=True)
        self.n_rows_ = int(len(y))
        self.fit_time_s_ = time.perf_counter() - t0
        return self

    def predict(self, contours_norm: np.ndarray, views: Sequence[int], size: np.ndarray | None = None) -> np.ndarray:
        """(N, 19, 3) metres from the ``views`` of contours_norm (N, K, n, 2); size: (N,) factors to multiply by."""
        c = np.asarray(contours_norm)
        present = np.zeros(c.shape[:2], bool)
        present[:, list(views)] = True
        pred = self.estimator_.predict(masked_features(c, present)).reshape(len(c), 19, 3)
        return pred if size is None else pred * np.asarray(size, dtype=np.float64)[:, None, None]


class ViewSubsetRegressor:
    """kNN, ridge or MLP regression from a view subset's normalised contours to root-relative joints.

    Args:
        kind: "knn", "ridge" or "mlp".
        views: rig view indices used as input (sorted).
        n_neighbors: k for "knn".
        alphas: penalties for "ridge" (:class:`~silpose.eval.ridge.BlockRidgeCV`).
        mlp: settings for "mlp" (:class:`MLPSettings`).

    Fitted attributes: ``estimator_`` (the sklearn estimator, or a :class:`GlobalScaledMLP`),
    ``fit_time_s_``.
    """

    def __init__(self, kind: str, views: Sequence[int], n_neighbors: int = 5,
                 alphas: Sequence[float] = RIDGE_ALPHAS, mlp: MLPSettings = MLPSettings()) -> None:
        self.kind = kind
        self.views = tuple(sorted(int(v) for v in views))
        self.n_neighbors = n_neighbors
        self.alphas = tuple(alphas)
        self.mlp = mlp

    def fit(self, contours_norm: np.ndarray, joints: np.ndarray, size: np.ndarray | None = None,
            groups: np.ndarray | None = None) -> "ViewSubsetRegressor":
        """contours_norm: (N, K, n, 2) normalised training contours; joints: (N, 19, 3) metres;
        size: optional (N,) factors (stature / 1.75 m): the target becomes root-relative joints / size;
        groups: (N,) walker of each row, required for "mlp" (its validation split is by walker)."""
        t0 = time.perf_counter()
        x = _features(contours_norm, self.views)
        y = root_relative(np.asarray(joints, dtype=np.float64))
        if size is not None:
            y = y / np.asarray(size, dtype=np.float64)[:, None, None]
        y = y.reshape(len(x), -1)
        if self.kind == "knn":
            est = KNeighborsRegressor(n_neighbors=min(self.n_neighbors, len(x)), weights="distance")
        elif self.kind == "ridge":
            est = BlockRidgeCV(alphas=self.alphas)
        elif self.kind == "mlp":
            if groups is None:
                raise ValueError("the MLP baseline needs groups (the walker of each training row)")
            self.estimator_ = fit_mlp(x, y, groups, self.mlp, overwrite_x=not np.shares_memory(x, contours_norm))
            self.fit_time_s_ = time.perf_counter() - t0
            return self
        else:
            raise ValueError(f"kind must be 'knn', 'ridge' or 'mlp', got {self.kind!r}")
        self.estimator_ = est.fit(x, y)
        self.fit_time_s_ = time.perf_counter() - t0
        return self

    def predict(self, contours_norm: np.ndarray, size: np.ndarray | None = None) -> np.ndarray:
        """contours_norm: (N, K, n, 2) (all rig views; only ``views`` are read) -> (N, 19, 3) metres;
        size: (N,) factors to multiply by, required when ``fit`` got them."""
        x = _features(contours_norm, self.views)
        pred = self.estimator_.predict(x).reshape(len(x), 19, 3)
        return pred if size is None else pred * np.asarray(size, dtype=np.float64)[:, None, None]
