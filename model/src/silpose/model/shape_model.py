"""The shape+structure model: an MPPCA prior over multi-view contours and 3D joints (paper sections 3-4).

Training vectors are built by :class:`~silpose.model.features.FeatureLayout` (paper eq. 4):
the modelled views' normalised contours followed by the weighted root-relative joints. A mixture
of PPCA (:class:`silpose.model.mppca.MPPCA`, paper eq. 3) is the prior density.

Fitting: :meth:`ShapeStructureModel.fit` on arrays in memory, :meth:`~ShapeStructureModel.fit_stream`
out of core over a dataset's Parquet shards (:mod:`silpose.model.streaming`, locally or on Ray);
both build the vectors with :func:`silpose.model.features.shape_vectors` and run the same EM.

Inference (paper section 4): :meth:`ShapeStructureModel.infer` checks its inputs
(:mod:`silpose.model.checks`), conditions on the present views (:class:`~silpose.model.posterior.Posterior`),
optionally robustly (:mod:`silpose.model.robust`), and adds plausibility, hypotheses and untangled contours
to the :class:`~silpose.model.result.InferenceResult`.

The model is a scikit-learn estimator: ``fit(X, y)`` with X the multi-view pixel contours (N, K, n, 2)
and y the joints, ``predict(X)`` the joints, ``score(X, y)`` the negative mean joint error (cm), and
``get_params`` / ``set_params``, so ``clone``, ``GridSearchCV`` and ``cross_val_score`` work on it.
"""

from __future__ import annotations

import time
from typing import Callable, Sequence

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.exceptions import NotFittedError

from silpose.shared.metrics import pose_error_cm
from silpose.shared.skeleton import N_JOINTS

from .checks import check_contours, check_views, model_inputs
from .features import FeatureLayout, shape_vectors
from .hypotheses import consensus_choice, top_hypotheses
from .mixing import Mixing, agreeing_choice, mixed_joints, vote_agreement
from .mppca import DEFAULT_INIT_ROWS, MPPCA, pool_mixtures
from .plausibility import PlausibilityCalibration, convex_in_every_view
from .posterior import Posterior
from .result import InferenceResult
from .robust import RobustSettings, robust_infer
from .shards import split_global_rows
from .streaming import DatasetShards
from .untangle import untangle as untangle_contours

__all__ = ["ShapeStructureModel", "InferenceResult", "ModelNotFittedError"]

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
# n_fits (ShapeStructureModel): single fits on small data carry about +-10 % of joint error from their k-means start
# alone (default preset, 200 held-out walkers, 5 seeds, standard noise, robust inference: 4.53-5.49 cm); 5 fits
# pooled gave 4.40, clean 3.27 against 3.40-3.92.
DEFAULT_N_COMPONENTS = 60
DEFAULT_N_LATENT = 40
DEFAULT_STRUCTURE_WEIGHT = 30.0
DEFAULT_NOISE_VARIANCE = 0.03
_FEATURE_BLOCK = 4096  # rows per block of features()


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
            (:func:`silpose.model.mppca.pool_mixtures`): the prior is the average of the fits' densities
            (measured: the module's comment on the defaults). Inference costs as much as a mixture of
            n_fits x n_components components. In-memory fits only.
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
        return MPPCA(n_components=int(self.n_components), n_latent=int(self.n_latent), tol=float(self.tol),
                     max_iter=int(self.max_iter), n_init=int(self.n_init), init_params=init_params,
                     noise_dof=bool(self.noise_dof), random_state=seed, callback=self.callback, verbose=self.verbose)

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
        views = check_views(self.views, n_rig)
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
        views = check_views(self.views, n_rig)
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
        mixing: Mixing | bool | None = None,
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
            mixing: the weights of the posterior mean ``joints`` (:mod:`silpose.model.mixing`): None = the model's
                calibration ``mixing_`` when it has one, else the mixture's own responsibilities; False = the
                mixture's own; a :class:`~silpose.model.mixing.Mixing` = that one.
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
        inputs = model_inputs(self.fitted_layout(), self.n_rig_views_, contours_px, views_present, input_views,
                              centroid, scale)
        posterior = self.posterior()
        mix = getattr(self, "mixing_", None) if mixing is None or mixing is True else (mixing or None)
        want = hypotheses > 0 or mix is not None  # component means (hypotheses) come from the last pass only
        if settings is None:
            res, comp = posterior.infer(inputs, s2, components=want)
        else:
            res, comp = robust_infer(posterior, inputs, s2, settings, want)
        cal = getattr(self, "plausibility_", None)
        if cal is not None and cal.applies_to(s2):
            res.plausibility = cal.percentile(res.log_marginal, inputs.present)
            # a likelihood percentile cannot flag a smooth blob: convex silhouettes are flagged too
            res.implausible = cal.implausible(res.plausibility) | convex_in_every_view(inputs.contours, inputs.present)
        if mix is not None:  # calibrated weights of the posterior mean (silpose.model.mixing)
            agree = vote_agreement(comp, posterior.pair_headings(inputs, s2)) if mix.needs_votes else None
            res.joints = mixed_joints(comp, res.responsibilities, mix.temperature(inputs.present.sum(axis=1)), agree,
                                      mix.vote_weight)
        if hypotheses > 0:
            hyp = top_hypotheses(comp, res.responsibilities, int(hypotheses))
            if consensus and hyp.k > 1:  # votes from the observed input, not the robust pseudo-observations
                hyp.chosen = consensus_choice(hyp, posterior.pair_headings(inputs, s2))
            elif mix is not None:  # the hypothesis facing the calibrated answer's way (silpose.model.mixing)
                hyp.chosen = agreeing_choice(hyp, res.joints)
            res.hypotheses = hyp
        if untangle:
            res.contours_norm, res.contours_px = untangle_contours(res.contours_norm, res.contours_px)
        return res

    def empty_result(self, n: int, noise_variance: float | None = None, *, hypotheses: int = 0,
                     robust: bool | RobustSettings = False, **_ignored) -> InferenceResult:
        """The result :meth:`infer` with these options would give ``n`` frames without any observed view (they
        cannot be inferred): NaN, no view present, the option's fields at their fill values
        (:meth:`InferenceResult.nan <silpose.model.result.InferenceResult.nan>`). Other ``infer`` options are
        accepted and ignored."""
        layout = self.fitted_layout()
        s2 = self.noise_variance if noise_variance is None else noise_variance
        cal = getattr(self, "plausibility_", None)
        return InferenceResult.nan(n, layout.views, layout.n_points, int(self.mixture_.weights_.shape[0]),
                                   plausibility=cal is not None and cal.applies_to(s2), hypotheses=int(hypotheses),
                                   robust=bool(robust))

    def posterior(self) -> Posterior:
        """The :class:`~silpose.model.posterior.Posterior` of the fitted mixture (kept with its cache of
        conditioners until the mixture, layout or rig change)."""
        layout = self.fitted_layout()
        post = getattr(self, "_posterior", None)
        if post is None or post.mixture is not self.mixture_ or post.layout is not layout or post.rig is not self.rig_:
            post = Posterior(self.mixture_, layout, self.rig_)
            self._posterior = post
        return post


def _joints_array(y, name: str) -> np.ndarray:
    """Joints as float64 (N, 19, 3) from (N, 19, 3) or flattened (N, 57); ValueError naming ``name`` otherwise."""
    j = np.asarray(y, dtype=np.float64)
    if j.ndim == 2 and j.shape[1] == 3 * N_JOINTS:
        j = j.reshape(len(j), N_JOINTS, 3)
    if j.ndim != 3 or j.shape[1:] != (N_JOINTS, 3):
        raise ValueError(f"{name} must have shape (N, {N_JOINTS}, 3) or (N, {3 * N_JOINTS}), got {j.shape}")
    return j
