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
from contextlib import nullcontext
from typing import Callable, Sequence

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.exceptions import NotFittedError

from silpose.shared.metrics import pose_error_cm
from silpose.shared.skeleton import N_JOINTS

from .checks import check_contours, model_inputs
from .defaults import DEFAULT_N_COMPONENTS, DEFAULT_N_LATENT, DEFAULT_NOISE_VARIANCE, DEFAULT_STRUCTURE_WEIGHT
from .features import FeatureLayout, shape_vectors_in_blocks
from .fitting import (check_hyperparameters, hyperparameter_record, joints_array, model_layout, new_mixture,
                      selected_shards, training_arrays)
from .inference_options import complete_result, inference_plan
from .mixing import Mixing
from .mppca import DEFAULT_INIT_ROWS, pool_mixtures
from .plausibility import PlausibilityCalibration
from .posterior import Posterior
from .result import InferenceResult
from .robust import RobustSettings, robust_infer
from .streaming import DatasetShards

__all__ = ["ShapeStructureModel", "InferenceResult", "ModelNotFittedError"]



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
        return hyperparameter_record(self)

    def features(self, contours_px: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """Shape vectors (N, d) for rig-indexed pixel contours (N, n_rig_views, n, 2) and joints (N, 19, 3).

        Built in blocks of rows (:func:`~silpose.model.features.shape_vectors_in_blocks`)."""
        return shape_vectors_in_blocks(self.fitted_layout(), self.n_rig_views_, contours_px, joints, self.rig_)

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
        check_hyperparameters(self)
        rig = self.rig if rig is None else rig
        c, j = training_arrays(X, y, rig)  # float32 contours stay float32 (converted block by block in features())
        self.flat_targets_ = np.ndim(y) == 2
        self.layout_ = model_layout(self, c.shape[1], c.shape[2], rig)
        self.n_rig_views_ = c.shape[1]
        self.rig_ = rig
        X = self.features(c, j)
        del c, j  # the inputs' copies are not needed during EM
        t0 = time.perf_counter()
        if int(self.n_fits) == 1:
            self.mixture_ = new_mixture(self, init_params).fit(X)
        else:  # n_fits EM fits from seeds random_state + i, pooled into one mixture (class docstring)
            fits = [new_mixture(self, init_params, i).fit(X) for i in range(int(self.n_fits))]
            self.mixture_ = pool_mixtures(fits, X)
        self.fit_time_ = time.perf_counter() - t0
        self.n_train_ = int(X.shape[0])
        return self

    def fit_stream(self, root, split: str = "train", *, rows=None, executor: str = "local",
                   workers: int | None = None, init_rows: int | None = None,
                   init_params: dict | None = None, cache: bool = True) -> "ShapeStructureModel":
        """Fit the prior out of core: EM streams over the Parquet shards of ``root``/``split``.

        Args:
            root: dataset folder; split: its split to read.
            rows: optional global row indices (0 .. rows in the split - 1, shard order) to fit on;
                None = every row.
            executor: "local" (one shard at a time in this process) or "ray" (one Ray task per shard).
            workers: CPUs of the local Ray instance when this process starts one (None = all cores).
            init_rows: rows of the k-means + PPCA initialisation subsample (None = the MPPCA default).
            init_params: optional explicit MPPCA start (needs n_init = 1).
            cache: with the local executor, build each shard's vectors once and read them back from a
                temporary file in later EM passes (``DatasetShards.feature_cache``; the same fit, faster).
        Every shard's vectors come from :func:`~silpose.model.features.shape_vectors`, as in :meth:`fit`;
        memory is bounded by one shard (see ``silpose.model.streaming``). Returns self.
        """
        check_hyperparameters(self)
        source = DatasetShards.open(root, split, executor=executor, workers=workers)
        return self.fit_shards(source, rows=rows, init_rows=init_rows, init_params=init_params,
                               where=f"{root} split {split!r}", cache=cache)

    def fit_shards(self, source: DatasetShards, *, rows=None, init_rows: int | None = None,
                   init_params: dict | None = None, where: str = "dataset", cache: bool = True) -> "ShapeStructureModel":
        """Fit by streaming EM over a planned :class:`~silpose.model.streaming.DatasetShards` (from
        ``DatasetShards.open``); ``rows`` are global row indices over its shards, ``where`` names the
        data in errors, ``cache`` as in :meth:`fit_stream`. Returns self."""
        check_hyperparameters(self)
        if int(self.n_fits) != 1:
            raise ValueError(f"n_fits = {self.n_fits}: pooled fits need the in-memory fit (fit), not the streaming one")
        n_rig = source.n_rig_views
        layout = model_layout(self, n_rig, source.n_points, source.rig)
        source = selected_shards(source.with_layout(layout), rows, where)
        self.layout_ = layout
        self.n_rig_views_ = n_rig
        self.rig_ = source.rig
        t0 = time.perf_counter()
        with source.feature_cache() if cache else nullcontext(source) as src:
            self.mixture_ = new_mixture(self, init_params).fit_stream(
                src, init_rows=DEFAULT_INIT_ROWS if init_rows is None else int(init_rows))
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
        err = pose_error_cm(pred, joints_array(y, "y"))
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
            untangle: make every reconstructed contour a simple polygon (:mod:`silpose.model.untangle`, all of a
                batch's at once: ~0.2 ms a contour).
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
        settings, mix, want = inference_plan(self, robust, mixing, hypotheses)
        inputs = model_inputs(self.fitted_layout(), self.n_rig_views_, contours_px, views_present, input_views,
                              centroid, scale)
        posterior = self.posterior()
        if settings is None:
            res, comp = posterior.infer(inputs, s2, components=want)
        else:
            res, comp = robust_infer(posterior, inputs, s2, settings, want)
        return complete_result(res, comp, posterior, inputs, s2, calibration=getattr(self, "plausibility_", None),
                               mix=mix, hypotheses=int(hypotheses), consensus=consensus, untangle=untangle)

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

