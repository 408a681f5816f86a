"""The shape+structure model: an MPPCA prior over multi-view contours and 3D joints (paper sections 3-4).

Training vectors are built by :class:`~silpose.model.features.FeatureLayout` (paper eq. 4):
the modelled views' normalised contours followed by the weighted root-relative joints. A mixture
of PPCA (:class:`silpose.model.mppca.MPPCA`, paper eq. 3) is the prior density.

Inference (paper section 4): the observed dimensions are the *present views'* contour
coordinates; the missing dimensions are the absent views' contours and the whole structure block.
Missing dimensions are marginalised by dropping their rows, never zero-filled; rows with different
missing-view patterns are grouped and conditioned separately. Every modelled view gets a
reconstruction: missing views from the conditional mean, present views from their Bayesian
reconstruction ``mu_a + W_a E[x | a]`` (the shape model of [8]). The numerics are the exact Gaussian
conditioning of :mod:`silpose.model.conditioning` (the tests check it against dense conditioning).

Fitting: :meth:`ShapeStructureModel.fit` on arrays in memory, :meth:`~ShapeStructureModel.fit_stream`
out of core over a dataset's Parquet shards (:mod:`silpose.model.streaming`, locally or on Ray);
both build the vectors with :func:`silpose.model.features.shape_vectors` and run the same EM.

The model is a scikit-learn estimator: ``fit(X, y)`` with X the multi-view pixel contours (N, K, n, 2)
and y the joints, ``predict(X)`` the joints, ``score(X, y)`` the negative mean joint error (cm), and
``get_params`` / ``set_params``, so ``clone``, ``GridSearchCV`` and ``cross_val_score`` work on it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.exceptions import NotFittedError

from silpose.shared.metrics import pose_error_cm
from silpose.shared.skeleton import N_JOINTS

from .checks import check_contours, check_factors, check_present
from .conditioning import Conditioner
from .features import FeatureLayout, denormalise_contours, normalise_contours, shape_vectors
from .hypotheses import Hypotheses, consensus_choice, heading, top_hypotheses
from .mppca import DEFAULT_INIT_ROWS, MPPCA, pool_mixtures
from .plausibility import PlausibilityCalibration, convex_in_every_view, view_subsets
from .provenance import manifest_sha256
from .excursions import trim_excursions
from .reindex import reindex_contours
from .robust import RobustSettings, frame_noise_variance, point_weights, snap_correspondences
from .untangle import untangle as untangle_contours
from .shards import split_global_rows
from .stature import REFERENCE_STATURE, estimate_stature
from .streaming import DatasetShards

# Defaults. History: chosen 2026-11-22 by validation joint error on the `default` preset (M 20, q 40, w 30,
# s2 0.03 in the stature joint frame; grids in git history). Re-measured 2026-11-30 (issue 12) after the
# training walkers were dressed like the test's (silpose.datagen.subjects) with `silpose train --select`
# (silpose.model.selection: score = mean of the validation joint error given all views and given one view,
# ragged validation outlines; held-out log-likelihood; only fits whose EM moves) on the default preset's
# 1,440 fit / 360 validation samples with --roughness 1, q 20/30/40 x M 5/10/15/20 x s2 0.01/0.03/0.1, w 30:
#   EM moves only with >= ~5 samples per component per latent dimension; the best such fit is M 10, q 30,
#   s2 0.03 (val 3.92 cm all views / 9.60 cm one view); frozen fits score better (M 15, q 40: 3.47 / 8.46)
#   but are their k-means partition with one PCA per cluster.
# On the paper preset (18,000 fitted samples) M 20, q 40 moves (14, 3.5, 1.5 nats in its first iterations;
# held-out 2.58 cm, 2,789 nats/sample). Re-measured 2026-11-30 (session 6) on the paper preset's training split:
# 18,000 fitted, 600 held-out walkers, one EM start, tol 0.1, mean pose error cm, 4 views, clean / the standard
# test noise with robust inference / the earlier milder noise (1 px jitter, 3 patches of 16 points at 4 px):
#   M x q   20x40 2.58/3.67/2.75   30x50 2.34/3.41/2.48   40x40 2.40/3.35/2.54   40x50 2.33/3.35/2.48
#           40x60 2.31/3.30/2.46   60x40 2.35/3.18/2.46   60x50 2.28/3.19/2.40   80x40 2.29/3.12/2.41
#           100x30 2.41/3.07/2.51
# More components help most under noise; 80 x 40 and 60 x 50 sit at or below 6 samples per component per latent
# dimension (the rule below). M 60, q 40 (held-out 2.38 cm all views, 6.22 one view, 2,957 nats/sample; 7.59 cm
# one view and 2,790 nats at M 20) is the default since. On the default preset's 1,800 samples no larger fit
# moves (M 20 q 30 freezes at its k-means start; 20x20, 30x15, 40x10 move but give 4.32-5.10 cm clean against
# 3.68 for 10x30), so `silpose train` lowers M (to 10), then q, for smaller data
# (silpose.app.training.supported_size: >= 6 samples per component per latent dimension), which gives M 10, q 30
# on the default preset -- the selection's choice -- and M 60, q 40 on the paper preset. Since session 7 the
# trainer counts the mirrored people of a mirror-symmetric rig (silpose.model.augment, `silpose train --mirror`):
# the default preset's 1,800 fitted walkers and their 1,800 mirror images give M 15, q 40 (200 held-out walkers,
# robust, seeds 0/1/2: clean 2.77/2.90/3.12 cm, standard noise 3.82/3.83/4.32 cm, against 3.68 and 4.55 for
# M 10, q 30 without mirrors; 20x40, 15x50 and 25x30 with mirrors were within 0.1-0.3 cm of 15x40).
DEFAULT_N_COMPONENTS = 60
DEFAULT_N_LATENT = 40
DEFAULT_STRUCTURE_WEIGHT = 30.0
DEFAULT_NOISE_VARIANCE = 0.03
_FEATURE_BLOCK = 4096  # rows per block of features()
_CONDITIONER_CACHE_BYTES = 256 << 20  # cached Conditioners of one model (ShapeStructureModel._conditioner)


@dataclass
class InferenceResult:
    """Output of :meth:`ShapeStructureModel.infer` for N frames and K modelled views.

    Attributes:
        joints: (N, 19, 3) root-relative joints, metres, mixture posterior mean.
        joints_best: (N, 19, 3) the most probable component's conditional mean, metres.
        joint_std: (N, 19, 3) posterior standard deviation per coordinate, metres.
        contours_norm: (N, K, n, 2) reconstructed normalised contours of every modelled view.
        contours_px: (N, K, n, 2) reconstructions in pixels; NaN where the view's normalisation is unknown.
        centroid: (N, K, 2) px normalisation centroid used (NaN where unknown).
        scale: (N, K) px normalisation scale used (NaN where unknown).
        views_present: (N, K) bool, which modelled views were observed.
        responsibilities: (N, M) component posteriors given the observed rows.
        log_marginal: (N,) log density of the observed rows under the prior (nats; with robust inference
            still that of the observed input).
        views: rig indices of the K modelled views.
        plausibility: (N,) % of held-out training inputs with the same view subset whose log marginal is
            lower (``silpose.model.plausibility``); None when the model has no calibration for this noise.
        implausible: (N,) bool, plausibility below the calibration's flag percentile; None as above.
        hypotheses: the top-K hypotheses (``infer(hypotheses=K)``), else None.
        robust_weights: (N, K, n) final per-point weights of robust inference (0 for absent views), else None.
        log_marginal_robust: (N,) log density of the last robust pass's pseudo-observations, else None.
        noise_variance: (N,) observation noise s^2 each frame was conditioned with by robust inference's
            adaptive noise (``silpose.model.robust``), else None (the model's or the given s^2).
        excursions_trimmed: (N, K) bool, views whose excursions (shadows, blobs, bitten holes) robust inference
            trimmed before its final pass (``silpose.model.excursions``; ``robust_weights`` then index the trimmed
            contour), else None.
        reindexed: (N, K) bool, views whose points robust inference slid back along their outline before its final
            pass (``silpose.model.reindex``), else None.
        robust_input_px: (N, K, n, 2) the observed contours robust inference's final pass started from: the input
            with those excursions trimmed and slides undone (``robust_weights`` index these points), else None.
    """

    joints: np.ndarray
    joints_best: np.ndarray
    joint_std: np.ndarray
    contours_norm: np.ndarray
    contours_px: np.ndarray
    centroid: np.ndarray
    scale: np.ndarray
    views_present: np.ndarray
    responsibilities: np.ndarray
    log_marginal: np.ndarray
    views: tuple[int, ...] = field(default=())
    plausibility: np.ndarray | None = None
    implausible: np.ndarray | None = None
    hypotheses: Hypotheses | None = None
    robust_weights: np.ndarray | None = None
    log_marginal_robust: np.ndarray | None = None
    noise_variance: np.ndarray | None = None
    excursions_trimmed: np.ndarray | None = None
    reindexed: np.ndarray | None = None
    robust_input_px: np.ndarray | None = None


def _replace_rows(full: InferenceResult, part: InferenceResult, rows: np.ndarray) -> None:
    """Write ``part`` (the results of frames ``rows`` of ``full``, inferred again) into ``full``, per-frame field by field."""
    n = len(full.joints)
    for name in full.__dataclass_fields__:
        value, new = getattr(full, name), getattr(part, name)
        if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == n and isinstance(new, np.ndarray):
            value[rows] = new


class ModelNotFittedError(NotFittedError, RuntimeError):
    """A ShapeStructureModel used before ``fit`` (scikit-learn's NotFittedError; a RuntimeError as before)."""


class ShapeStructureModel(RegressorMixin, BaseEstimator):
    """Mixture-of-PPCA prior over multi-view contours + 3D joints, with Bayesian inference.

    A scikit-learn estimator (module docstring): X = pixel contours (N, K, n, 2) of the rig's K views (NaN
    rows mark absent views in ``predict``), y = joints (N, 19, 3) metres, or flattened (N, 57).

    Parameters (stored only; validated in ``fit``):
        n_components: mixture components M.
        n_latent: latent dimension q of each PPCA component.
        structure_weight: factor on the root-relative joints in the shape vector (docs/conventions.md, "Model").
        views: rig view indices to model (vector order); None = every view of the training data.
        noise_variance: observation noise s^2 on the contours at inference, normalised contour units^2.
        joint_frame: "stature" (model the joints of each walker scaled to a 1.75 m stature measured from
            the calibrated silhouettes, ``silpose.model.stature``; needs the rig), "metres" (the paper's
            raw root-relative joints), or None = "stature" when ``fit`` gets a rig, else "metres".
        n_fits: EM fits from the seeds random_state, random_state + 1, ..., pooled into one mixture of
            n_fits x n_components components, each fit's weights divided by n_fits
            (:func:`silpose.model.mppca.pool_mixtures`): the prior is the average of the fits' densities.
            Single fits on small data carry about +-10 % of joint error from their k-means start alone
            (default preset, 200 held-out walkers, 5 seeds, standard noise, robust inference: 4.53-5.49 cm);
            5 fits pooled gave 4.40, clean 3.27 against 3.40-3.92. Inference costs as much as a mixture
            of n_fits x n_components components. In-memory fits only.
        noise_dof: correct the components' noise variances for the degrees of freedom their fit used
            (``MPPCA(noise_dof=True)``): the maximum-likelihood ones are biased low when a component has few
            rows for its q (the train / held-out log-likelihood gap of issue 12); the joints hardly change.
        tol, max_iter, n_init, random_state, callback, verbose: passed to :class:`~silpose.model.mppca.MPPCA`.
        rig: the ``silpose.shared.camera.Rig`` of the K views, used when ``fit`` is not given one (so that
            ``fit(X, y)`` alone, e.g. inside ``GridSearchCV``, can use the 'stature' joint frame).

    Fitted attributes: ``layout_`` (FeatureLayout), ``mixture_`` (fitted MPPCA), ``n_rig_views_``,
    ``rig_`` (Rig or None), ``fit_time_`` (s), ``n_train_``, ``flat_targets_`` (``fit`` got y as (N, 57):
    ``predict`` returns that shape too);
    ``plausibility_`` (:class:`~silpose.model.plausibility.PlausibilityCalibration` or None) after
    :meth:`calibrate_plausibility`.
    """

    def __init__(
        self,
        n_components: int = DEFAULT_N_COMPONENTS,
        n_latent: int = DEFAULT_N_LATENT,
        *,
        structure_weight: float = DEFAULT_STRUCTURE_WEIGHT,
        views: Sequence[int] | None = None,
        noise_variance: float = DEFAULT_NOISE_VARIANCE,
        joint_frame: str | None = None,
        noise_dof: bool = True,
        tol: float = 1e-4,
        max_iter: int = 200,
        n_init: int = 3,
        n_fits: int = 1,
        random_state: int | None = 0,
        callback: Callable | None = None,
        verbose: int = 0,
        rig=None,
    ) -> None:
        self.n_components = n_components
        self.n_latent = n_latent
        self.structure_weight = structure_weight
        self.views = views
        self.noise_variance = noise_variance
        self.joint_frame = joint_frame
        self.noise_dof = noise_dof
        self.tol = tol
        self.max_iter = max_iter
        self.n_init = n_init
        self.n_fits = n_fits
        self.random_state = random_state
        self.callback = callback
        self.verbose = verbose
        self.rig = rig

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False  # X is (N, K, n, 2) contours, not a table
        tags.target_tags.required = True
        tags.target_tags.multi_output = True
        tags.target_tags.single_output = False
        return tags

    # ------------------------------------------------------------------ fitting
    def hyperparameters(self) -> dict:
        """Hyperparameters as a JSON-friendly dict (no callback, verbose or rig): what model files, training
        reports and evaluation settings record. ``get_params()`` is scikit-learn's (every constructor argument)."""
        return {
            "n_components": int(self.n_components),
            "n_latent": int(self.n_latent),
            "structure_weight": float(self.structure_weight),
            "views": None if self.views is None else [int(v) for v in self.views],
            "noise_variance": float(self.noise_variance),
            "joint_frame": self.joint_frame,
            "noise_dof": bool(self.noise_dof),
            "tol": float(self.tol),
            "max_iter": int(self.max_iter),
            "n_init": int(self.n_init),
            "n_fits": int(self.n_fits),
            "random_state": None if self.random_state is None else int(self.random_state),
        }

    def _check_hyperparameters(self) -> None:
        if int(self.n_components) < 1:
            raise ValueError(f"n_components must be >= 1, got {self.n_components}")
        if int(self.n_latent) < 1:
            raise ValueError(f"n_latent must be >= 1, got {self.n_latent}")
        if int(self.n_fits) < 1:
            raise ValueError(f"n_fits must be >= 1, got {self.n_fits}")
        if not np.isfinite(self.noise_variance) or self.noise_variance < 0:
            raise ValueError(f"noise_variance must be finite and >= 0, got {self.noise_variance}")
        if self.joint_frame not in (None, "metres", "stature"):
            raise ValueError(f"joint_frame must be 'metres', 'stature' or None, got {self.joint_frame!r}")

    def _resolve_joint_frame(self, rig) -> str:
        """The joint frame a fit with ``rig`` uses (None -> 'stature' with a rig, else 'metres')."""
        frame = self.joint_frame or ("stature" if rig is not None else "metres")
        if frame == "stature" and rig is None:
            raise ValueError("joint_frame 'stature' needs the camera rig: pass rig= to fit (or joint_frame='metres')")
        return frame

    def _make_mixture(self, init_params: dict | None = None, fit_index: int = 0) -> MPPCA:
        seed = self.random_state
        if fit_index and seed is not None:  # fit i of n_fits starts from seed + i
            seed = int(seed) + int(fit_index)
        return MPPCA(
            n_components=int(self.n_components),
            n_latent=int(self.n_latent),
            tol=float(self.tol),
            max_iter=int(self.max_iter),
            n_init=int(self.n_init),
            init_params=init_params,
            noise_dof=bool(self.noise_dof),
            random_state=seed,
            callback=self.callback,
            verbose=self.verbose,
        )

    def features(self, contours_px: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """Shape vectors (N, d) for rig-indexed pixel contours (N, n_rig_views, n, 2) and joints (N, 19, 3).

        Built in blocks of rows (every step is row-wise) so the float64 temporaries of the normalisation
        are bounded by a block, whatever N."""
        layout = self.fitted_layout()
        n = len(contours_px)
        if n <= _FEATURE_BLOCK:
            return shape_vectors(layout, self.n_rig_views_, contours_px, joints, self.rig_)
        out = np.empty((n, layout.dim))
        for start in range(0, n, _FEATURE_BLOCK):
            sl = slice(start, start + _FEATURE_BLOCK)
            out[sl] = shape_vectors(layout, self.n_rig_views_, contours_px[sl], joints[sl], self.rig_)
        return out

    def fit(self, X: np.ndarray, y: np.ndarray, rig=None, *,
            init_params: dict | None = None) -> "ShapeStructureModel":
        """Fit the prior.

        Args:
            X: contours_px, (N, K, n, 2) contours in pixels for all K views of the rig (``views`` selects among them).
            y: joints, (N, 19, 3) joint positions in metres (absolute or root-relative), or flattened (N, 57).
            rig: optional ``silpose.shared.camera.Rig`` of the K views (kept for persistence and PNG inference);
                None = the ``rig`` parameter.
            init_params: optional explicit MPPCA start (see ``MPPCA(init_params=...)``; needs n_init = 1).
        Returns:
            self.
        """
        self._check_hyperparameters()
        rig = self.rig if rig is None else rig
        raw = np.asarray(X)
        # float32 input is checked as is and converted block by block in features(), never as a whole
        c = raw if raw.dtype == np.float32 and raw.ndim == 4 else check_contours(raw, "contours_px")
        j = _joints_array(y, "joints")
        self.flat_targets_ = np.ndim(y) == 2
        if j.shape[0] != c.shape[0]:
            raise ValueError(f"contours_px has {c.shape[0]} samples but joints has {j.shape[0]}")
        if not np.all(np.isfinite(c)):
            raise ValueError("contours_px contains NaN or inf")
        if not np.all(np.isfinite(j)):
            raise ValueError("joints contains NaN or inf")
        n_rig = c.shape[1]
        if rig is not None and len(rig) != n_rig:
            raise ValueError(f"rig has {len(rig)} cameras but contours_px has {n_rig} views")
        views = tuple(range(n_rig)) if self.views is None else tuple(int(v) for v in self.views)
        bad = [v for v in views if not 0 <= v < n_rig]
        if bad:
            raise ValueError(f"views {bad} do not exist: the data have {n_rig} views (0..{n_rig - 1})")
        self.layout_ = FeatureLayout(views, c.shape[2], N_JOINTS, float(self.structure_weight),
                                     self._resolve_joint_frame(rig))
        self.n_rig_views_ = n_rig
        self.rig_ = rig
        X = self.features(c, j)
        del c, j, raw  # the inputs' copies are not needed during EM
        t0 = time.perf_counter()
        if int(self.n_fits) == 1:
            self.mixture_ = self._make_mixture(init_params).fit(X)
        else:  # n_fits EM fits from seeds random_state + i, pooled into one mixture (class docstring)
            fits = [self._make_mixture(init_params, i).fit(X) for i in range(int(self.n_fits))]
            self.mixture_ = pool_mixtures(fits, X)
        self.fit_time_ = time.perf_counter() - t0
        self.n_train_ = int(X.shape[0])
        return self

    def fit_stream(self, root, split: str = "train", *, rows=None, executor: str = "local",
                   workers: int | None = None, init_rows: int | None = None,
                   init_params: dict | None = None) -> "ShapeStructureModel":
        """Fit the prior out of core: EM streams over the Parquet shards of ``root``/``split``.

        Args:
            root: dataset folder; split: its split to read.
            rows: optional global row indices (0 .. rows in the split - 1, shard order) to fit on;
                None = every row.
            executor: "local" (one shard at a time in this process) or "ray" (one Ray task per shard).
            workers: CPUs of the local Ray instance when this process starts one (None = all cores).
            init_rows: rows of the k-means + PPCA initialisation subsample (None = the MPPCA default).
            init_params: optional explicit MPPCA start (needs n_init = 1).
        Every shard's vectors come from :func:`~silpose.model.features.shape_vectors`, as in :meth:`fit`;
        memory is bounded by one shard (see ``silpose.model.streaming``). Returns self.
        """
        self._check_hyperparameters()
        source = DatasetShards.open(root, split, executor=executor, workers=workers)
        return self.fit_shards(source, rows=rows, init_rows=init_rows, init_params=init_params,
                               where=f"{root} split {split!r}")

    def fit_shards(self, source: DatasetShards, *, rows=None, init_rows: int | None = None,
                   init_params: dict | None = None, where: str = "dataset") -> "ShapeStructureModel":
        """Fit by streaming EM over a planned :class:`~silpose.model.streaming.DatasetShards` (from
        ``DatasetShards.open``); ``rows`` are global row indices over its shards, ``where`` names the
        data in errors. See :meth:`fit_stream`. Returns self."""
        self._check_hyperparameters()
        if int(self.n_fits) != 1:
            raise ValueError(f"n_fits = {self.n_fits}: pooled fits need the in-memory fit (fit), not the streaming one")
        n_rig = source.n_rig_views
        views = tuple(range(n_rig)) if self.views is None else tuple(int(v) for v in self.views)
        bad = [v for v in views if not 0 <= v < n_rig]
        if bad:
            raise ValueError(f"views {bad} do not exist: the data have {n_rig} views (0..{n_rig - 1})")
        layout = FeatureLayout(views, source.n_points, N_JOINTS, float(self.structure_weight),
                               self._resolve_joint_frame(source.rig))
        source = source.with_layout(layout)
        if rows is not None:
            idx = np.unique(np.asarray(rows, dtype=np.int64))
            total = sum(source.shard_rows())
            if idx.size == 0 or idx[0] < 0 or idx[-1] >= total:
                raise ValueError(f"rows must be non-empty indices in 0..{total - 1} ({where})")
            source = source.select(split_global_rows(idx, source.shard_rows()))
        self.layout_ = layout
        self.n_rig_views_ = n_rig
        self.rig_ = source.rig
        t0 = time.perf_counter()
        self.mixture_ = self._make_mixture(init_params).fit_stream(
            source, init_rows=DEFAULT_INIT_ROWS if init_rows is None else int(init_rows))
        self.fit_time_ = time.perf_counter() - t0
        self.n_train_ = int(self.mixture_.n_fit_samples_)
        return self

    def fit_dataset(self, split) -> "ShapeStructureModel":
        """Fit on a ``silpose.shared.dataset.DatasetSplit`` (its contours, joints and rig).

        Records the dataset folder and the sha256 of its ``manifest.json`` (when present) in
        ``dataset_info_``, which persistence stores in the model file.
        """
        self.fit(split.contours, split.joints, rig=split.rig)
        info: dict = {"n_samples": int(len(split.joints))}
        files = list(getattr(split, "files", []) or [])
        if files:
            root = files[0].parent
            info["root"] = str(root)
            info["manifest_sha256"] = manifest_sha256(root)
            info["config_name"] = (split.metadata.get("config") or {}).get("name")
            info["generator_config"] = split.metadata.get("config")
        self.dataset_info_ = info
        return self

    # ------------------------------------------------------------------ scoring
    def fitted_layout(self) -> FeatureLayout:
        """The shape-vector layout of a fitted model (``layout_``); :class:`ModelNotFittedError` when not fitted."""
        if not hasattr(self, "layout_"):
            raise ModelNotFittedError("ShapeStructureModel is not fitted: call fit() or load_model() first")
        return self.layout_

    def score_samples(self, contours_px: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """(N,) log density of the full shape+structure vectors (contours and joints observed)."""
        return self.mixture_.score_samples(self.features(contours_px, joints))

    # ------------------------------------------------------------------ scikit-learn prediction
    def predict(self, X: np.ndarray) -> np.ndarray:
        """Joints (N, 19, 3) metres, root-relative (the posterior mean of :meth:`infer`) from contours X
        (N, K_in, n, 2) px, K_in = the rig's or the modelled views; a view whose contour holds NaN is absent.
        Returns (N, 57) when the model was fitted on flattened joints."""
        self.fitted_layout()
        c = check_contours(X, "contours_px")
        joints = self.infer(c, np.isfinite(c).all(axis=(2, 3))).joints
        return joints.reshape(len(joints), -1) if getattr(self, "flat_targets_", False) else joints

    def score(self, X: np.ndarray, y: np.ndarray, sample_weight: np.ndarray | None = None) -> float:
        """Negative mean joint error, cm (higher is better): ``-mean pose_error_cm(predict(X), y)`` (the paper's
        error, ``silpose.shared.metrics``), weighted by ``sample_weight`` (N,) when given."""
        pred = self.predict(X).reshape(-1, N_JOINTS, 3)
        err = pose_error_cm(pred, _joints_array(y, "y"))
        return -float(np.average(err, weights=sample_weight))

    def calibrate_plausibility(self, contours_px: np.ndarray, *, n_draws: int | None = None,
                               seed: int = 0) -> "ShapeStructureModel":
        """Calibrate the plausibility percentiles on held-out inputs (:mod:`silpose.model.plausibility`).

        contours_px: (N, K_rig, n, 2) clean pixel contours of training walkers the fit did not see.
        Sets ``plausibility_`` (saved in the model file); returns self.
        """
        kwargs = {} if n_draws is None else {"n_draws": int(n_draws)}
        self.plausibility_ = None  # the calibration's own inferences must not look one up
        self.plausibility_ = PlausibilityCalibration.fit(self, contours_px, seed=seed, **kwargs)
        return self

    # ------------------------------------------------------------------ inference
    def infer(
        self,
        contours_px: np.ndarray,
        views_present: np.ndarray | None = None,
        noise_variance: float | None = None,
        *,
        input_views: Sequence[int] | None = None,
        centroid: np.ndarray | None = None,
        scale: np.ndarray | None = None,
        hypotheses: int = 0,
        consensus: bool = False,
        robust: bool | RobustSettings = False,
        untangle: bool = False,
    ) -> InferenceResult:
        """Infer joints and reconstruct every modelled view's contour from the observed views.

        Args:
            contours_px: (N, K_in, n, 2) pixel contours. By default K_in is either the number of
                modelled views (model order) or the number of rig views (rig order); otherwise pass
                ``input_views``. Rows of absent views may hold anything (e.g. NaN).
            views_present: (N, K_in) bool; None = every input view present.
            noise_variance: observation noise s^2 (normalised units^2); None = the model's ``noise_variance``.
            input_views: rig indices of the K_in input views. Input views that are not modelled are ignored;
                modelled views missing from the input are treated as absent.
            centroid, scale: optional (N, K_in, 2) / (N, K_in) true pixel normalisation factors, used to map
                absent views' reconstructions to pixels (present views use their own factors).
            hypotheses: K > 0 also returns the K most probable distinct component hypotheses
                (``InferenceResult.hypotheses``, :mod:`silpose.model.hypotheses`).
            consensus: with ``hypotheses``, choose the single answer among them by the vote of the pairs of
                present views (:func:`~silpose.model.hypotheses.consensus_choice`; needs >= 3 present views);
                False (the default) = the most probable. Off by default: with the issue-12 training it made
                single frames worse (default preset, 4 views, the standard noise: flips 0.2 -> 1.0 %, pose
                5.01 -> 5.31 cm; ``silpose eval``'s E6 table).
            robust: True or :class:`~silpose.model.robust.RobustSettings`: iteratively reweighted
                conditioning with heavy-tailed per-point noise (:mod:`silpose.model.robust`); the result
                describes the last pass, ``log_marginal`` (and the plausibility) the observed input.
            untangle: make every reconstructed contour a simple polygon (:mod:`silpose.model.untangle`; about
                1 ms per self-intersecting contour).
        Returns:
            :class:`InferenceResult` over the K modelled views.
        """
        s2 = self.noise_variance if noise_variance is None else noise_variance
        if not np.isfinite(s2) or s2 < 0:
            raise ValueError(f"noise_variance must be finite and >= 0, got {s2}")
        s2 = float(s2)
        if int(hypotheses) < 0:
            raise ValueError(f"hypotheses must be >= 0, got {hypotheses}")
        settings = RobustSettings() if robust is True else (robust or None)
        present, c_mod, cen_true, sc_true = self._prepare(contours_px, views_present, input_views, centroid, scale)
        want = hypotheses > 0  # component means (hypotheses) come from the last pass only
        if settings is None:
            res, comp = self._infer_prepared(c_mod, present, cen_true, sc_true, s2, components=want)
        else:
            res, comp = self._infer_robust(c_mod, present, cen_true, sc_true, s2, settings, want)
            observed_lm = res.log_marginal.copy()  # _replace_rows below writes into res's arrays
            trimmed = np.zeros(present.shape, dtype=bool)
            reindexed = np.zeros(present.shape, dtype=bool)
            work = c_mod
            # shadows, blobs, holes (silpose.model.excursions), then slides along the outline (silpose.model.reindex)
            steps = ([(trim_excursions, settings.excursions, trimmed)] * int(settings.excursion_passes)
                     + [(reindex_contours, settings.reindex, reindexed)] * int(settings.reindex_passes))
            settled = set()  # a step that changed nothing would change nothing on its next pass either
            for step, step_settings, done in steps:
                if step in settled:
                    continue
                new, changed = step(work, res.contours_px, present, step_settings)
                rows = np.flatnonzero(changed.any(axis=1))
                if rows.size == 0:
                    settled.add(step)
                    continue
                work = np.where(changed[..., None, None], new, work)
                done |= changed
                again, again_comp = self._infer_robust(work[rows], present[rows], cen_true[rows], sc_true[rows], s2,
                                                       settings, want)
                _replace_rows(res, again, rows)
                if comp is not None:
                    comp[rows] = again_comp
            res.log_marginal = observed_lm  # of the input as observed, excursions and all
            res.excursions_trimmed = trimmed
            res.reindexed = reindexed
            res.robust_input_px = np.asarray(work, dtype=np.float64)
        cal = getattr(self, "plausibility_", None)
        if cal is not None and cal.applies_to(s2):
            res.plausibility = cal.percentile(res.log_marginal, present)
            # a likelihood percentile cannot flag a smooth blob: convex silhouettes are flagged too
            res.implausible = cal.implausible(res.plausibility) | convex_in_every_view(c_mod, present)
        if hypotheses > 0:
            hyp = top_hypotheses(comp, res.responsibilities, int(hypotheses))
            if consensus and hyp.k > 1:  # votes from the observed input, not the robust pseudo-observations
                hyp.chosen = consensus_choice(hyp, self._pair_headings(c_mod, present, s2))
            res.hypotheses = hyp
        if untangle:
            res.contours_norm, res.contours_px = untangle_contours(res.contours_norm, res.contours_px)
        return res

    def _infer_robust(self, c_mod: np.ndarray, present: np.ndarray, cen_true: np.ndarray, sc_true: np.ndarray,
                      s2: float, settings: RobustSettings, want: bool) -> tuple[InferenceResult, np.ndarray | None]:
        """Robust inference (``silpose.model.robust``) of prepared inputs (:meth:`_prepare`): the Gaussian pass,
        the adaptive noise, then ``settings.iterations`` reweighted passes; returns the last pass's result (with
        ``log_marginal`` that of the input, ``log_marginal_robust``, ``robust_weights``, ``noise_variance``) and,
        with ``want``, its component means (as :meth:`_infer_prepared`)."""
        res, comp = self._infer_prepared(c_mod, present, cen_true, sc_true, s2, components=False)
        observed_lm = res.log_marginal
        if settings.noise_scale is not None:  # adaptive observation noise per frame (silpose.model.robust)
            with np.errstate(invalid="ignore", over="ignore"):
                norm_obs = normalise_contours(c_mod)[0]
            s2_rows = frame_noise_variance(norm_obs, res.contours_norm, present, s2, settings.noise_scale)
            res, comp = self._infer_prepared(c_mod, present, cen_true, sc_true, s2_rows, components=False)
        else:
            s2_rows = s2
        for it in range(int(settings.iterations)):
            matched, dist = snap_correspondences(c_mod, res.contours_px, int(settings.window))
            u = np.where(present[..., None], point_weights(dist, settings.threshold, settings.scale_floor_px), 0.0)
            pseudo = np.where(present[..., None, None], res.contours_px + u[..., None] * (matched - res.contours_px),
                              c_mod)
            last = it == int(settings.iterations) - 1
            res, comp = self._infer_prepared(pseudo, present, cen_true, sc_true, s2_rows, components=want and last)
        if settings.noise_scale is not None:
            res.noise_variance = s2_rows
        res.log_marginal_robust = res.log_marginal
        res.log_marginal = observed_lm
        res.robust_weights = u
        return res, comp

    def _prepare(self, contours_px, views_present, input_views, centroid, scale):
        """Inputs in the model's view order: (present (N, K), contours (N, K, n, 2) px, true centroid
        (N, K, 2) and scale (N, K) where given (NaN otherwise)); shapes and values checked."""
        layout = self.fitted_layout()
        c_in = check_contours(contours_px, "contours_px", n_points=layout.n_points)
        n, k_in = c_in.shape[:2]
        cols = self._input_columns(k_in, input_views)  # (K,) input column of each modelled view or -1
        present_in = check_present(views_present, n, k_in)
        kmod = layout.n_views
        cen_in, sc_in = check_factors(centroid, scale, n, k_in)
        if np.array_equal(cols, np.arange(k_in)):  # input columns are the modelled views, in order: no copies
            present, c_mod = present_in, c_in
            cen_true = cen_in if cen_in is not None else np.full((n, kmod, 2), np.nan)
            sc_true = sc_in if sc_in is not None else np.full((n, kmod), np.nan)
        else:
            present = np.zeros((n, kmod), dtype=bool)
            c_mod = np.full((n, kmod, layout.n_points, 2), np.nan)
            cen_true = np.full((n, kmod, 2), np.nan)
            sc_true = np.full((n, kmod), np.nan)
            for p, col in enumerate(cols):
                if col < 0:
                    continue
                present[:, p] = present_in[:, col]
                c_mod[:, p] = c_in[:, col]
                if cen_in is not None:
                    cen_true[:, p] = cen_in[:, col]
                    sc_true[:, p] = sc_in[:, col]
        all_present = bool(present.all())
        finite = np.isfinite(c_mod).all() if all_present else np.isfinite(c_mod).all(axis=(2, 3))[present].all()
        if not finite:
            bad = ~np.isfinite(c_mod).all(axis=(2, 3)) & present
            r, p = np.argwhere(bad)[0]
            raise ValueError(
                f"contours_px has NaN/inf in an observed view: frame {r}, view {layout.views[p]} "
                f"({int(bad.sum())} observed views affected); mark such views absent in views_present"
            )
        none = ~present.any(axis=1)
        if none.any():
            raise ValueError(
                f"every modelled view is missing in {int(none.sum())} frame(s) (first: frame "
                f"{int(np.flatnonzero(none)[0])}); at least one of views {layout.views} must be observed"
            )
        return present, c_mod, cen_true, sc_true

    def _infer_prepared(self, c_mod: np.ndarray, present: np.ndarray, cen_true: np.ndarray, sc_true: np.ndarray,
                        s2, components: bool = False) -> tuple[InferenceResult, np.ndarray | None]:
        """Normalise, condition (one Conditioner per present-view pattern and noise) and assemble the result.

        Inputs in the model's view order (:meth:`_prepare`); ``s2`` a float or (N,) one noise variance per
        frame (robust inference). With ``components`` also returns each component's conditional mean of the
        joints (N, M, 19, 3) metres, else None.
        """
        layout = self.fitted_layout()
        n, kmod = present.shape
        all_present = bool(present.all())
        # absent views may hold NaN (never read); absurd values (~1e300 px) overflow, caught below
        with np.errstate(invalid="ignore", over="ignore"):
            norm, cen, sc = normalise_contours(c_mod)
        overflow = present & ~(np.isfinite(sc) & np.isfinite(cen).all(axis=-1))  # (N, K): O(N K) check
        if overflow.any():
            r, p = np.argwhere(overflow)[0]
            raise ValueError(
                f"contours_px values too large to normalise (overflow) in an observed view: frame {r}, view "
                f"{layout.views[p]}; pixel coordinates must be finite and of image size"
            )
        if not all_present:  # keep the known factors for absent views
            cen = np.where(present[..., None], cen, cen_true)
            sc = np.where(present, sc, sc_true)

        d = layout.dim
        M = int(self.mixture_.weights_.shape[0])
        flat = norm.reshape(n, -1)
        per_row = np.ndim(s2) > 0
        if per_row:  # group by (pattern, noise): the noise level index joins the pattern columns
            levels, level_of = np.unique(np.asarray(s2, dtype=np.float64), return_inverse=True)
            keys, inverse = np.unique(np.column_stack([present, level_of.reshape(-1)]), axis=0, return_inverse=True)
            patterns, group_s2 = keys[:, :kmod].astype(bool), levels[keys[:, kmod]]
            inverse = inverse.reshape(-1)
        elif all_present or n == 1:
            patterns, inverse = present[:1], np.zeros(n, dtype=np.intp)
        else:
            patterns, inverse = np.unique(present, axis=0, return_inverse=True)
            inverse = inverse.reshape(-1)
        if not per_row:
            group_s2 = np.full(len(patterns), float(s2))
        cmeans = None
        if len(patterns) == 1:  # the common case: no fancy-index copies
            x_obs = flat if patterns[0].all() else flat[:, layout.observed_mask(patterns[0])[: layout.contour_dim]]
            post = self._conditioner(patterns[0], float(group_s2[0]))(x_obs, return_components=components)
            mean, best, var, resp, logm = (post.reconstruction, post.best_mean, post.variance,
                                           post.responsibilities, post.log_marginal)
            cmeans = post.component_means
        else:
            mean = np.empty((n, d))
            best = np.empty((n, layout.structure_dim))
            var = np.empty((n, layout.structure_dim))
            resp = np.empty((n, M))
            logm = np.empty(n)
            if components:
                cmeans = np.empty((n, M, layout.structure_dim))
            for g, pattern in enumerate(patterns):
                rows = np.flatnonzero(inverse == g)
                x_obs = flat[rows][:, layout.observed_mask(pattern)[: layout.contour_dim]]
                post = self._conditioner(pattern, float(group_s2[g]))(x_obs, return_components=components)
                mean[rows], best[rows], var[rows] = post.reconstruction, post.best_mean, post.variance
                resp[rows], logm[rows] = post.responsibilities, post.log_marginal
                if components:
                    cmeans[rows] = post.component_means

        rec, joints = layout.split(mean)
        w = layout.structure_weight
        joints_best = best.reshape(n, layout.n_joints, 3) / w
        # Var[w s] = w^2 Var[s]  ->  std(s) = sqrt(Var[w s]) / w
        joint_std = np.sqrt(np.maximum(var, 0.0)).reshape(n, layout.n_joints, 3) / w
        comp_joints = None if cmeans is None else cmeans.reshape(n, M, layout.n_joints, 3) / w
        if layout.joint_frame == "stature":  # back from "a 1.75 m walker" to this walker's metres
            factor = self._stature(c_mod, present) / REFERENCE_STATURE
            joints, joints_best, joint_std = (a * factor[:, None, None] for a in (joints, joints_best, joint_std))
            if comp_joints is not None:
                comp_joints = comp_joints * factor[:, None, None, None]
        px = denormalise_contours(rec, cen, sc)
        res = InferenceResult(
            joints=joints,
            joints_best=joints_best,
            joint_std=joint_std,
            contours_norm=rec,
            contours_px=px,
            centroid=cen,
            scale=sc,
            views_present=present,
            responsibilities=resp,
            log_marginal=logm,
            views=layout.views,
        )
        return res, comp_joints

    def _pair_headings(self, c_mod: np.ndarray, present: np.ndarray, s2: float) -> np.ndarray:
        """(N, V) headings (radians) of the posterior mean joints given each pair of present views (V = K (K - 1) / 2
        columns, NaN where a view of the pair is absent); frames with fewer than 3 present views get no votes
        (all NaN). See :func:`~silpose.model.hypotheses.consensus_choice`."""
        layout = self.fitted_layout()
        n, kmod = present.shape
        pairs = [s for s in view_subsets(kmod) if len(s) == 2]
        votes = np.full((n, len(pairs)), np.nan)
        voting = present.sum(axis=1) >= 3
        if not voting.any():
            return votes
        with np.errstate(invalid="ignore", over="ignore"):
            norm, _, _ = normalise_contours(c_mod)
        flat = norm.reshape(n, -1)
        for j, pair in enumerate(pairs):
            pattern = np.zeros(kmod, dtype=bool)
            pattern[list(pair)] = True
            rows = np.flatnonzero(voting & present[:, pattern].all(axis=1))
            if rows.size == 0:
                continue
            x_obs = flat[rows][:, layout.observed_mask(pattern)[: layout.contour_dim]]
            post = self._conditioner(pattern, s2, structure_only=True)(x_obs)
            votes[rows, j] = heading(post.missing_mean.reshape(rows.size, layout.n_joints, 3))
        return votes

    def _stature(self, contours_mod: np.ndarray, present: np.ndarray) -> np.ndarray:
        """(N,) metres: stature measured from the present modelled views (``silpose.model.stature``)."""
        if self.rig_ is None:
            raise ValueError("this model's joints are in the 'stature' frame but it has no camera rig")
        cams = [self.rig_[v] for v in self.fitted_layout().views]
        return estimate_stature(contours_mod, cams, present)

    def _conditioner(self, pattern: np.ndarray, s2: float, structure_only: bool = False) -> Conditioner:
        """Cached :class:`~silpose.model.conditioning.Conditioner` for one present-view pattern and s^2.

        Its q x q factorisations depend only on the pattern and s^2, so they are computed once per
        (pattern, s^2) and fitted mixture; repeated single-frame calls then cost O((d_obs + d) q M).
        ``structure_only``: a conditioner whose mean covers the joints only (``Posterior.missing_mean``,
        (N, 57)), for the consensus votes.
        """
        cache = getattr(self, "_conditioner_cache", None)
        if cache is None or cache[0] is not self.mixture_:
            cache = (self.mixture_, {})
            self._conditioner_cache = cache
        key = (np.asarray(pattern, dtype=bool).tobytes(), s2, bool(structure_only))
        post = cache[1].pop(key, None)
        if post is None:
            layout = self.fitted_layout()
            det = np.arange(layout.structure_slice.start, layout.structure_slice.stop)
            post = Conditioner(
                self.mixture_, layout.observed_mask(pattern), s2, detail=det,
                reconstruct=not structure_only, detail_only=structure_only,
            )
        cache[1][key] = post  # most recently used last
        # bounded by bytes, least recently used first out: one conditioner holds O(d M q) floats (about 60 MB
        # for M 60, q 40 on 4 views), and a run may visit 2 (2^K - 1) view patterns per s^2
        total = sum(c.nbytes for c in cache[1].values())
        while total > _CONDITIONER_CACHE_BYTES and len(cache[1]) > 1:
            total -= cache[1].pop(next(iter(cache[1]))).nbytes
        return post

    def _input_columns(self, k_in: int, input_views: Sequence[int] | None) -> np.ndarray:
        """(K_mod,) input column of each modelled view, -1 when the input does not contain it."""
        layout = self.fitted_layout()
        if input_views is None:
            if k_in == self.n_rig_views_:
                input_views = tuple(range(k_in))
            elif k_in == layout.n_views:
                input_views = layout.views
            else:
                raise ValueError(
                    f"contours_px has {k_in} views; expected {layout.n_views} (the modelled views "
                    f"{layout.views}) or {self.n_rig_views_} (all rig views), or pass input_views"
                )
        input_views = [int(v) for v in input_views]
        if len(input_views) != k_in:
            raise ValueError(f"input_views names {len(input_views)} views but contours_px has {k_in}")
        unknown = [v for v in input_views if not 0 <= v < self.n_rig_views_]
        if unknown:
            raise ValueError(f"unknown view indices {unknown}: the model's rig has views 0..{self.n_rig_views_ - 1}")
        if len(set(input_views)) != len(input_views):
            raise ValueError(f"input_views has duplicates: {input_views}")
        return np.array([input_views.index(v) if v in input_views else -1 for v in layout.views])


def _joints_array(y, name: str) -> np.ndarray:
    """Joints as float64 (N, 19, 3) from (N, 19, 3) or flattened (N, 57); ValueError naming ``name`` otherwise."""
    j = np.asarray(y, dtype=np.float64)
    if j.ndim == 2 and j.shape[1] == 3 * N_JOINTS:
        j = j.reshape(len(j), N_JOINTS, 3)
    if j.ndim != 3 or j.shape[1:] != (N_JOINTS, 3):
        raise ValueError(f"{name} must have shape (N, {N_JOINTS}, 3) or (N, {3 * N_JOINTS}), got {j.shape}")
    return j
