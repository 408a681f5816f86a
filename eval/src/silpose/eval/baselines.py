"""Reference methods for E4 (paper §6; docs/conventions.md, "Evaluation protocol"): chance, kNN regression, ridge regression.

- **Chance** (:class:`ChanceBaseline`): the paper's "random draw of pose parameters from the
  training set" — each test example gets one training pose drawn uniformly at random, root-
  relative, scored with the same pose error (paper: 29 cm mean).
- **kNN / ridge** (:class:`ViewSubsetRegressor`): regress the 57 root-relative joint coordinates
  (metres) on the observed views' NORMALISED contours (each view ``(n, 2)`` flattened x0, y0, x1,
  ..., views concatenated in rig order) — the same inputs the MPPCA sees. One regressor is fitted
  per view subset on the clean training contours; at test time it gets exactly the noisy contours
  of that subset. kNN: ``sklearn.neighbors.KNeighborsRegressor`` (k = 5, distance-weighted);
  ridge: ``sklearn.linear_model.RidgeCV`` with the penalty chosen by efficient leave-one-out over
  ``alphas`` on the training data only.
  When the MPPCA models joints per stature (``silpose.model.stature``), the regressors get the same
  information: they regress the joints divided by each walker's measured ``stature / 1.75 m`` and
  multiply their prediction by the stature measured from the observed views (``size=``).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from sklearn.linear_model import RidgeCV
from sklearn.neighbors import KNeighborsRegressor

from silpose.shared.seeds import CHANCE_STREAM, derive_rng
from silpose.shared.skeleton import root_relative

__all__ = ["ChanceBaseline", "ViewSubsetRegressor", "RIDGE_ALPHAS"]

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
    c = np.asarray(contours_norm, dtype=np.float64)
    if c.ndim != 4 or c.shape[-1] != 2:
        raise ValueError(f"contours_norm must have shape (N, K, n, 2), got {c.shape}")
    bad = [v for v in views if not 0 <= v < c.shape[1]]
    if bad:
        raise ValueError(f"views {bad} not in the input's {c.shape[1]} views")
    return c[:, list(views)].reshape(len(c), -1)


class ViewSubsetRegressor:
    """kNN or ridge regression from a view subset's normalised contours to root-relative joints.

    Args:
        kind: "knn" or "ridge".
        views: rig view indices used as input (sorted).
        n_neighbors: k for "knn".
        alphas: penalties for "ridge" (RidgeCV).

    Fitted attributes: ``estimator_`` (the sklearn estimator).
    """

    def __init__(self, kind: str, views: Sequence[int], n_neighbors: int = 5,
                 alphas: Sequence[float] = RIDGE_ALPHAS) -> None:
        self.kind = kind
        self.views = tuple(sorted(int(v) for v in views))
        self.n_neighbors = n_neighbors
        self.alphas = tuple(alphas)

    def fit(self, contours_norm: np.ndarray, joints: np.ndarray, size: np.ndarray | None = None) -> "ViewSubsetRegressor":
        """contours_norm: (N, K, n, 2) normalised training contours; joints: (N, 19, 3) metres;
        size: optional (N,) factors (stature / 1.75 m): the target becomes root-relative joints / size."""
        x = _features(contours_norm, self.views)
        y = root_relative(np.asarray(joints, dtype=np.float64))
        if size is not None:
            y = y / np.asarray(size, dtype=np.float64)[:, None, None]
        y = y.reshape(len(x), -1)
        if self.kind == "knn":
            est = KNeighborsRegressor(n_neighbors=min(self.n_neighbors, len(x)), weights="distance")
        elif self.kind == "ridge":
            est = RidgeCV(alphas=self.alphas)
        else:
            raise ValueError(f"kind must be 'knn' or 'ridge', got {self.kind!r}")
        self.estimator_ = est.fit(x, y)
        return self

    def predict(self, contours_norm: np.ndarray, size: np.ndarray | None = None) -> np.ndarray:
        """contours_norm: (N, K, n, 2) (all rig views; only ``views`` are read) -> (N, 19, 3) metres;
        size: (N,) factors to multiply by, required when ``fit`` got them."""
        x = _features(contours_norm, self.views)
        pred = self.estimator_.predict(x).reshape(len(x), 19, 3)
        return pred if size is None else pred * np.asarray(size, dtype=np.float64)[:, None, None]
