"""The experiments of paper §6 (docs/conventions.md, "Evaluation protocol") on our data: E1-E4 as per-example result rows.

Inputs (the same for every method): the test split's CLEAN contours (px) are corrupted with the
configured noise (:data:`silpose.eval.noise.STANDARD_NOISE` unless told otherwise), deterministically
per ``(seed, sample_id)``; every method sees exactly these noisy contours of the views it is
given. Absent views are passed as absent (``views_present``), never as zeros. Contour errors
compare each reconstruction with the TRUE CLEAN contour of its view: present views' reconstructions
are mapped to pixels with the noisy input's own normalisation, missing views' with the view's true
(clean) factors. Pose errors are root-relative cm (:mod:`silpose.shared.metrics`).

- **E1** single-view vs multi-view training (paper Fig. 5). For each view k a model with
  ``views=(k,)`` is fitted on the same training split and given the noisy contour of view k; the
  4-view model is given the noisy contours of all 4 views of the same examples. Two capacities,
  labelled in ``training``: ``"single-view"`` has the 4-view model's hyperparameters (equal q, so
  K times the latent dimensions per view), ``"single-view, equal q per view"`` has q / K latent
  dimensions (rounded, >= 1; the 4-view model's share per view), the rest equal. Pose: mean over
  (example, k) of the single-view models vs mean over examples of the 4-view model. Contours:
  single-view model k's error in view k vs the 4-view model's error in view k. For reference E2's
  rows hold the 4-view model given view k alone.
- **E2** the 4-view model given every non-empty subset of views: 4; 3 (each view left out in
  turn); 2 and 1 (all combinations) — every subset on every example, so all combinations are
  covered equally (paper Fig. 8).
- **E3** noise sweep: each :class:`NoiseSpec` of ``config.sweep`` on the 4-view model with the
  input subsets ``config.sweep_inputs`` (default all views, and view 0 alone), and kNN/ridge with
  all views.
- **E4** chance (one random training pose per example), kNN / ridge regression fitted per view
  subset and the MLP baseline (one network for every subset, trained on clean and noisy copies of
  the training contours; :mod:`silpose.eval.baselines`) on the standard noisy inputs of E2. Each
  regressor's fitting time and prediction time per frame go to ``extra["baseline_timing"]``.
- **E6** hypotheses and flips, robust inference, missing-view contours against a nearest
  neighbour, self-intersections and plausibility flags (:mod:`silpose.eval.e6_inference`); its
  robust rows join E3's.
"""

from __future__ import annotations

import time
import warnings
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from typing import Callable, Sequence

import numpy as np
import pandas as pd

from silpose.model.plausibility import view_subsets
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.stature import REFERENCE_STATURE, estimate_stature
from silpose.shared.contours import normalise
from silpose.shared.metrics import chamfer_errors, pose_error_cm, pose_error_procrustes_cm
from silpose.shared.seeds import BASELINE_AUGMENT_STREAM, BASELINE_ROWS_STREAM, derive_rng, draw_subset

from .baselines import ChanceBaseline, MLPSettings, ViewDropoutMLP, ViewSubsetRegressor, group_split, masked_features
from .e6_inference import run_e6
from .noise import STANDARD_NOISE, NoiseSpec, apply_noise

__all__ = ["EvalConfig", "EvalData", "Evaluation", "DEFAULT_SWEEP", "E1_PER_VIEW", "view_subsets", "views_label"]

#: E1's ``training`` label of the single-view models with the 4-view model's latent dimensions per view (q / K).
E1_PER_VIEW = "single-view, equal q per view"

#: E3: the noise settings swept by default (magnitudes in px; see silpose.eval.noise).
DEFAULT_SWEEP: tuple[NoiseSpec, ...] = (
    NoiseSpec(label="clean"),
    *(NoiseSpec(label=f"jitter {m:g}px", jitter_px=m) for m in (0.5, 1.0, 2.0, 4.0)),
    *(NoiseSpec(label=f"patches {d:g}px", n_patches=3, patch_length=16, patch_depth_px=d) for d in (2.0, 4.0, 8.0, 16.0)),
    STANDARD_NOISE,
    NoiseSpec(label="standard before issue 12", jitter_px=1.0, n_patches=3, patch_length=16, patch_depth_px=4.0),
    NoiseSpec(label="mask mild", mask_holes=2, mask_hole_radius_px=3, mask_blobs=2, mask_blob_radius_px=3, mask_shadow_px=10),
    NoiseSpec(label="mask strong", mask_holes=4, mask_hole_radius_px=5, mask_blobs=4, mask_blob_radius_px=5, mask_shadow_px=20),
)

Progress = Callable[[str, int, int], None]  # (task description, completed, total)

#: rows per block of :meth:`Evaluation.train_normalised`.
_NORM_BLOCK = 4096

#: The regression baselines, in table order.
REGRESSORS = ("knn", "ridge", "mlp")


def views_label(views: Sequence[int]) -> str:
    """'0123'-style label of a view subset ('-' when empty)."""
    return "".join(str(int(v)) for v in views) or "-"


@dataclass
class EvalConfig:
    """Settings of one evaluation run.

    Attributes:
        n_test: test examples used (the first ``n_test`` of the split; None = all).
        seed: seed of the noise streams and the chance draws.
        noise: the test noise of E1, E2, E4.
        sweep: E3's noise settings.
        sweep_inputs: E3's input view subsets (None = all views and view 0 alone).
        knn_neighbors: k of the kNN baseline.
        mlp: the MLP baseline's settings; mlp_noisy_copies: noisy copies of each training walker it is
            trained on (besides the clean one; the test noise model ``noise``, other seeds).
        baseline_rows: training samples the ridge and MLP baselines see at most (None = all): beyond it
            they see this many, drawn uniformly by ``silpose.shared.seeds.draw_subset`` with the keys
            ``(seed, BASELINE_ROWS_STREAM)``, so their memory and time stay bounded (the MLP trains on
            ``(1 + mlp_noisy_copies) x baseline_rows`` rows). kNN and chance see every training sample (kNN
            holds one float32 copy of its views' rows). At 43,200 motions samples the cap changed the
            baselines' errors by less than the test set's noise (docs/training-at-scale.md).
        experiments: which of "E1".."E7" to run (E7, recordings: :mod:`silpose.eval.sequences`, run by
            :func:`silpose.eval.run.run_evaluation`).
    """

    n_test: int | None = None
    seed: int = 0
    noise: NoiseSpec = STANDARD_NOISE
    sweep: tuple[NoiseSpec, ...] = DEFAULT_SWEEP
    sweep_inputs: tuple[tuple[int, ...], ...] | None = None
    knn_neighbors: int = 5
    mlp: MLPSettings = field(default_factory=MLPSettings)
    mlp_noisy_copies: int = 2
    baseline_rows: int | None = 20_000
    experiments: tuple[str, ...] = ("E1", "E2", "E3", "E4", "E5", "E6", "E7")

    def to_dict(self) -> dict:
        return {
            "n_test": self.n_test,
            "seed": self.seed,
            "noise": self.noise.to_dict(),
            "sweep": [s.to_dict() for s in self.sweep],
            "sweep_inputs": None if self.sweep_inputs is None else [list(v) for v in self.sweep_inputs],
            "knn_neighbors": self.knn_neighbors,
            "mlp": {**asdict(self.mlp), "hidden": list(self.mlp.hidden)},
            "mlp_noisy_copies": self.mlp_noisy_copies,
            "baseline_rows": self.baseline_rows,
            "experiments": list(self.experiments),
        }


@dataclass
class EvalData:
    """Training and test arrays (N_train / N test examples, K views, n points).

    Attributes:
        train_contours: (N_train, K, n, 2) clean px; train_joints: (N_train, 19, 3) metres.
        test_ids: (N,) sample ids; test_joints: (N, 19, 3) metres; test_contours: (N, K, n, 2)
            clean px; test_centroid (N, K, 2), test_scale (N, K): their normalisation factors;
            test_masks: (N, K, H, W) uint8 or None.
        test_length, test_area: (N, K) contour length and silhouette area, px (None if not stored).
        image_size: (K, 2) (height, width) px per view.
        train_groups: (N_train,) walker of each training row (rows with identical subject parameters, and
            a row's mirrored and ragged copies; None: one walker per row).
        train_fitted: the first ``train_fitted`` training rows are samples the 4-view model was fitted on (set by
            ``silpose.eval.run.match_training_subset``; None: not known).
    """

    train_contours: np.ndarray
    train_joints: np.ndarray
    test_ids: np.ndarray
    test_joints: np.ndarray
    test_contours: np.ndarray
    test_centroid: np.ndarray
    test_scale: np.ndarray
    image_size: np.ndarray
    test_masks: np.ndarray | None = None
    rig: object = None
    test_length: np.ndarray | None = None
    test_area: np.ndarray | None = None
    train_groups: np.ndarray | None = None
    train_fitted: int | None = None

    @property
    def n_views(self) -> int:
        return int(self.test_contours.shape[1])

    @classmethod
    def from_splits(cls, train, test, n_test: int | None = None) -> "EvalData":
        """Build from two ``silpose.shared.dataset.DatasetSplit`` (test optionally with masks)."""
        n = len(test) if n_test is None else min(int(n_test), len(test))
        if n <= 0:
            raise ValueError("the test split is empty (or n_test <= 0)")
        clean = np.asarray(test.contours[:n], np.float64)
        _, cen, sc = normalise(clean)  # the same definition the dataset stores; recomputed in float64
        sizes = np.array([[cam.height, cam.width] for cam in test.rig.cameras], dtype=int)
        return cls(
            train_contours=np.asarray(train.contours, np.float64),
            train_joints=np.asarray(train.joints, np.float64),
            test_ids=np.asarray(test.sample_id[:n]),
            test_joints=np.asarray(test.joints[:n], np.float64),
            test_contours=clean,
            test_centroid=cen,
            test_scale=sc,
            image_size=sizes,
            test_masks=None if test.masks is None else test.masks[:n],
            rig=test.rig,
            test_length=None if "contour_length" not in test.extra else np.asarray(test.extra["contour_length"][:n]),
            test_area=None if "area" not in test.extra else np.asarray(test.extra["area"][:n]),
            train_groups=walker_groups(train.subject, len(train.sample_id)),
        )


def walker_groups(subject: dict, n: int) -> np.ndarray:
    """(n,) int walker index: rows whose subject parameters (dict of (n,) arrays; NaN = not applicable) are
    all equal are one walker. Without parameters every row is its own walker."""
    if not subject:
        return np.arange(n)
    cols = np.stack([np.nan_to_num(np.asarray(subject[k], np.float64), nan=-1e30) for k in sorted(subject)], axis=1)
    return np.unique(cols, axis=0, return_inverse=True)[1].reshape(-1)


@dataclass
class Evaluation:
    """Runs E1-E4 for one 4-view model and collects per-example rows.

    Args:
        data: the arrays.
        model: a fitted ``ShapeStructureModel`` over all views.
        config: the settings.
        progress: optional ``(description, completed, total)`` callback.
        single_view_models: optional {view: fitted single-view model}; missing ones are fitted.
    """

    data: EvalData
    model: object
    config: EvalConfig = field(default_factory=EvalConfig)
    progress: Progress | None = None
    single_view_models: dict = field(default_factory=dict)
    rows: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    extra: dict = field(default_factory=dict)  # E6's tables (silpose.eval.e6_inference)

    def __post_init__(self) -> None:
        self._chamfer_cache: dict = {}
        self._noisy: dict = {}
        self._regressors: dict = {}

    # ---------------------------------------------------------------- helpers
    def _tick(self, what: str, done: int, total: int) -> None:
        if self.progress is not None:
            self.progress(what, done, total)

    def noisy(self, spec: NoiseSpec) -> np.ndarray:
        """(N, K, n, 2) noisy test contours for ``spec`` (cached)."""
        if spec not in self._noisy:
            d = self.data
            self._noisy[spec] = apply_noise(spec, d.test_contours, d.test_ids, self.config.seed, masks=d.test_masks)
        return self._noisy[spec]

    def _present(self, views: Sequence[int]) -> np.ndarray:
        p = np.zeros((len(self.data.test_ids), self.data.n_views), bool)
        p[:, list(views)] = True
        return p

    def _add(self, base: dict, **arrays) -> None:
        n = len(self.data.test_ids)
        row = {"sample_id": self.data.test_ids}
        row.update({k: np.full(n, v, dtype=object if isinstance(v, str) else None) for k, v in base.items()})
        row.update(arrays)
        self.rows.append(row)

    def score_model(self, model, noisy: np.ndarray, views: Sequence[int], **infer_kwargs) -> dict:
        """Infer from ``noisy`` with only ``views`` present (``infer_kwargs`` go to ``model.infer``, e.g.
        ``robust=True``); per-example errors.

        Returns:
            dict of (N,) arrays: pose_cm, pose_pa_cm, chamfer_px (one-sided true->recon, mean over
            the modelled views), chamfer_sym_px, chamfer_observed_px, chamfer_missing_px and
            chamfer_v{k} for each rig view (NaN where view k is not modelled).
        """
        d = self.data
        present = self._present(views)
        res = model.infer(noisy, views_present=present, centroid=d.test_centroid, scale=d.test_scale, **infer_kwargs)
        recon = np.full(d.test_contours.shape[:2] + res.contours_px.shape[2:], np.nan)
        recon[:, list(res.views)] = res.contours_px
        one, sym = chamfer_errors(d.test_contours, recon, d.image_size, cache=self._chamfer_cache, keys=d.test_ids)
        modelled = np.zeros(d.n_views, bool)
        modelled[list(res.views)] = True
        obs = present & modelled
        miss = ~present & modelled
        with np.errstate(invalid="ignore"), _quiet_nanmean():
            out = {
                "pose_cm": pose_error_cm(res.joints, d.test_joints),
                "pose_pa_cm": pose_error_procrustes_cm(res.joints, d.test_joints),
                "chamfer_px": np.nanmean(one, axis=1),
                "chamfer_sym_px": np.nanmean(sym, axis=1),
                "chamfer_observed_px": np.nanmean(np.where(obs, one, np.nan), axis=1),
                "chamfer_missing_px": np.nanmean(np.where(miss, one, np.nan), axis=1),
            }
        for k in range(d.n_views):
            out[f"chamfer_v{k}"] = one[:, k]
        return out

    def single_view_model(self, k: int, per_view: bool = False):
        """The model trained on view k alone, fitted on first use with the 4-view model's hyperparameters;
        ``per_view``: with q / K latent dimensions instead of q (cached under the key ``(k, "per_view")``)."""
        key = (int(k), "per_view") if per_view else k
        if key not in self.single_view_models:
            params = dict(self.model.get_params())
            params["views"] = (int(k),)
            if per_view:
                params["n_latent"] = self.per_view_latent()
            with warnings.catch_warnings(record=True) as caught:  # keep the progress display clean
                warnings.simplefilter("always")
                self.single_view_models[key] = ShapeStructureModel(**params).fit(
                    self.data.train_contours, self.data.train_joints, rig=self.data.rig
                )
            for w in caught:
                self.notes.append(f"E1 single-view model {k}{' (q/K)' if per_view else ''}: "
                                  f"{w.category.__name__}: {w.message}")
        return self.single_view_models[key]

    def per_view_latent(self) -> int:
        """q / K (rounded, >= 1): the 4-view model's latent dimensions per modelled view."""
        return max(1, int(round(int(self.model.n_latent) / len(self.model.layout_.views))))

    def train_normalised(self) -> np.ndarray:
        """(N_train, K, n, 2) float32: the training contours normalised (``silpose.shared.contours.normalise``, in
        float64, then rounded; computed once, in blocks of rows: the baselines, whose rows are float32, and E6's
        nearest neighbours share it)."""
        if not hasattr(self, "_train_norm"):
            c = self.data.train_contours
            self._train_norm = np.empty(c.shape, np.float32)
            for i in range(0, len(c), _NORM_BLOCK):
                self._train_norm[i:i + _NORM_BLOCK] = normalise(c[i:i + _NORM_BLOCK])[0]
        return self._train_norm

    def baseline_rows(self) -> np.ndarray:
        """Sorted indices of the training samples the ridge and MLP baselines see (``config.baseline_rows``);
        the count and the cap go to ``extra["baseline_rows"]``."""
        if not hasattr(self, "_baseline_rows"):
            n, cap = len(self.data.train_joints), self.config.baseline_rows
            self._baseline_rows = draw_subset(n, cap, self.config.seed, BASELINE_ROWS_STREAM)
            self.extra["baseline_rows"] = {"cap": cap, "rows": int(len(self._baseline_rows)), "of": int(n)}
            if len(self._baseline_rows) < n:
                self.notes.append(f"ridge and MLP baselines: {len(self._baseline_rows)} of the {n} training samples "
                                  f"(baseline_rows cap, seeded draw)")
        return self._baseline_rows

    def regressor(self, kind: str, views: Sequence[int]):
        """kNN (every training sample) or ridge (``baseline_rows``) regressor for a view subset, fitted on the
        clean training contours (cached), or the MLP baseline bound to the subset."""
        key = (kind, tuple(views))
        if kind == "mlp":
            return _BoundViews(self.mlp_baseline(), tuple(views))
        if key not in self._regressors:
            rows = np.arange(len(self.data.train_joints)) if kind == "knn" else self.baseline_rows()
            every = len(rows) == len(self.data.train_joints)
            norm = self.train_normalised() if every else self.train_normalised()[rows]
            px = self.data.train_contours if every else self.data.train_contours[rows]
            joints = self.data.train_joints if every else self.data.train_joints[rows]
            reg = ViewSubsetRegressor(kind, views, n_neighbors=self.config.knn_neighbors).fit(
                norm, joints, size=self._size(px, views))
            self._timing(kind)["fit_s"] += reg.fit_time_s_
            self._regressors[key] = reg
        return self._regressors[key]

    def _timing(self, kind: str) -> dict:
        table = self.extra.setdefault("baseline_timing", {})
        return table.setdefault(kind, {"fit_s": 0.0, "predict_s": 0.0, "frames": 0})

    def mlp_baseline(self) -> ViewDropoutMLP:
        """The MLP baseline (fitted on first use): the training walkers of ``baseline_rows``, clean and
        ``mlp_noisy_copies`` times with the test noise model (noise seeds and view subsets from
        ``BASELINE_AUGMENT_STREAM``), each row given a random view subset (its size uniform in 1..K); validation
        split by walker. The rows are normalised copy by copy straight into the network's float32 input array,
        training rows first (no float64 copy of all the rows, no second copy)."""
        if not hasattr(self, "_mlp"):
            d, cfg = self.data, self.config
            t0 = time.perf_counter()
            rows = self.baseline_rows()
            n, K = len(rows), d.n_views
            groups = rows if d.train_groups is None else np.asarray(d.train_groups)[rows]
            rng = derive_rng(cfg.seed, BASELINE_AUGMENT_STREAM)
            seeds = [int(rng.integers(2**31 - 1)) for _ in range(cfg.mlp_noisy_copies)]
            reps = 1 + cfg.mlp_noisy_copies
            present = np.zeros((reps * n, K), bool)
            sizes = rng.integers(1, K + 1, size=reps * n)
            for r, k in enumerate(sizes):
                present[r, rng.choice(K, size=k, replace=False)] = True
            stature = self._size(d.train_contours[:1], (0,)) is not None  # per-stature joints: size from the given views
            size = np.empty(reps * n) if stature else None
            all_groups = np.tile(groups, reps)
            tr, va = group_split(all_groups, cfg.mlp.validation_fraction, cfg.mlp.random_state)
            order = np.concatenate([tr, va])  # the network's row order: training rows first (scaled in place)
            where = np.empty_like(order)
            where[order] = np.arange(len(order))
            x = np.empty((reps * n, int(np.prod(d.train_contours.shape[1:])) + K), np.float32)
            for c in range(reps):  # copy c, in blocks of rows (the noise is per sample id: blocks change nothing)
                for lo in range(0, n, _NORM_BLOCK):
                    ids = rows[lo:lo + _NORM_BLOCK]  # sample ids: the noise seeds (the noise stream's seed differs)
                    px = d.train_contours[ids]
                    if c and not cfg.noise.needs_masks:
                        px = apply_noise(cfg.noise, px, ids, seeds[c - 1], masks=None)
                    block = np.arange(c * n + lo, c * n + lo + len(ids))
                    x[where[block]] = masked_features(normalise(px)[0], present[block])
                    if stature:
                        p = present[block]
                        for pattern in np.unique(p, axis=0):
                            sel = np.flatnonzero((p == pattern).all(axis=1))
                            size[block[sel]] = self._size(px[sel], tuple(np.flatnonzero(pattern)))
                    del px
            joints = np.concatenate([d.train_joints[rows]] * reps)
            self._mlp = ViewDropoutMLP(cfg.mlp).fit_features(x, joints[order], all_groups[order],
                                                             size=None if size is None else size[order])
            del x
            self._timing("mlp")["fit_s"] += time.perf_counter() - t0
            self.extra.setdefault("mlp_baseline", {}).update(
                rows=int(reps * n), walkers=int(len(np.unique(groups))), epochs=int(self._mlp.estimator_.n_epochs_),
                best_epoch=int(self._mlp.estimator_.best_epoch_),
                val_rmse_m=float(self._mlp.estimator_.val_rmse_), net_fit_s=float(self._mlp.fit_time_s_))
        return self._mlp

    def _size(self, contours_px: np.ndarray, views: Sequence[int]) -> np.ndarray | None:
        """(N,) stature / 1.75 m from ``views`` of (N, K, n, 2) pixel contours when the MPPCA models joints
        per stature (the baselines then get the same information), else None."""
        layout = getattr(self.model, "layout_", None)
        if getattr(layout, "joint_frame", "metres") != "stature" or self.data.rig is None:
            return None
        v = list(views)
        return estimate_stature(contours_px[:, v], [self.data.rig[k] for k in v]) / REFERENCE_STATURE

    def score_regressor(self, kind: str, views: Sequence[int], noisy: np.ndarray) -> dict:
        """Root-relative pose errors (cm) of the ``kind`` regressor given ``views`` of ``noisy``."""
        reg = self.regressor(kind, views)
        t0 = time.perf_counter()
        pred = reg.predict(normalise(noisy)[0], size=self._size(noisy, views))
        t = self._timing(kind)
        t["predict_s"] += time.perf_counter() - t0
        t["frames"] += len(pred)
        return {"pose_cm": pose_error_cm(pred, self.data.test_joints),
                "pose_pa_cm": pose_error_procrustes_cm(pred, self.data.test_joints)}

    # ---------------------------------------------------------------- experiments
    def run(self) -> "Evaluation":
        """Run the configured experiments (E5 figures are drawn by :mod:`silpose.eval.e5_figures`)."""
        for name in ("E1", "E2", "E3", "E4", "E6"):
            if name in self.config.experiments:
                t0 = time.perf_counter()
                getattr(self, f"run_{name.lower()}")()
                self.timings[name] = time.perf_counter() - t0
        for t in self.extra.get("baseline_timing", {}).values():
            t["ms_per_frame"] = 1e3 * t["predict_s"] / t["frames"] if t["frames"] else float("nan")
        return self

    def run_e1(self) -> None:
        K = self.data.n_views
        all_views = tuple(range(K))
        noisy = self.noisy(self.config.noise)
        total = 4 * K + 1
        for i, (per_view, label) in enumerate(((False, "single-view"), (True, E1_PER_VIEW))):
            for k in range(K):
                self._tick(f"E1: fitting the view-{k} model{' (q/K)' if per_view else ''}", 2 * i * K + k, total)
                self.single_view_model(k, per_view)
            for k in range(K):
                self._tick(f"E1: single-view model {k}{' (q/K)' if per_view else ''}", (2 * i + 1) * K + k, total)
                s = self.score_model(self.single_view_model(k, per_view), noisy, (k,))
                self._add(dict(experiment="E1", method="mppca", training=label, trained_views=str(k),
                               input_views=str(k), n_input_views=1, noise=self.config.noise.label), **s)
        self._tick("E1: multi-view model", 4 * K, total)
        s = self.score_model(self.model, noisy, all_views)
        self._add(dict(experiment="E1", method="mppca", training="multi-view", trained_views=views_label(all_views),
                       input_views=views_label(all_views), n_input_views=K, noise=self.config.noise.label), **s)
        self._tick("E1", total, total)

    def run_e2(self) -> None:
        K = self.data.n_views
        noisy = self.noisy(self.config.noise)
        subsets = view_subsets(K)
        for i, views in enumerate(subsets):
            self._tick(f"E2: views {views_label(views)}", i, len(subsets))
            s = self.score_model(self.model, noisy, views)
            self._add(dict(experiment="E2", method="mppca", training="multi-view", trained_views=views_label(range(K)),
                           input_views=views_label(views), n_input_views=len(views), noise=self.config.noise.label), **s)
        self._tick("E2", len(subsets), len(subsets))

    def run_e3(self) -> None:
        K = self.data.n_views
        inputs = self.config.sweep_inputs or (tuple(range(K)), (0,))
        specs = [s for s in self.config.sweep if not (s.needs_masks and self.data.test_masks is None)]
        skipped = [s.label for s in self.config.sweep if s not in specs]
        if skipped:
            self.notes.append(f"E3: skipped {skipped}: the test masks were not loaded")
        total = len(specs) * (len(inputs) + len(REGRESSORS))
        step = 0
        for spec in specs:
            noisy = self.noisy(spec)
            for views in inputs:
                self._tick(f"E3: {spec.label}, views {views_label(views)}", step, total)
                s = self.score_model(self.model, noisy, views)
                self._add(dict(experiment="E3", method="mppca", training="multi-view", trained_views=views_label(range(K)),
                               input_views=views_label(views), n_input_views=len(views), noise=spec.label), **s)
                step += 1
            for kind in REGRESSORS:
                self._tick(f"E3: {spec.label}, {kind}", step, total)
                s = self.score_regressor(kind, tuple(range(K)), noisy)
                self._add(dict(experiment="E3", method=kind, training="multi-view", trained_views=views_label(range(K)),
                               input_views=views_label(range(K)), n_input_views=K, noise=spec.label), **s)
                step += 1
        for spec in list(self._noisy):
            if spec != self.config.noise:
                del self._noisy[spec]
        self._tick("E3", total, total)

    def run_e6(self) -> None:
        run_e6(self)

    def run_e4(self) -> None:
        K = self.data.n_views
        noisy = self.noisy(self.config.noise)
        chance = ChanceBaseline(random_state=self.config.seed).fit(self.data.train_joints)
        pred = chance.predict(len(self.data.test_ids))
        self._add(dict(experiment="E4", method="chance", training="-", trained_views="-", input_views="-",
                       n_input_views=0, noise="-"),
                  pose_cm=pose_error_cm(pred, self.data.test_joints),
                  pose_pa_cm=pose_error_procrustes_cm(pred, self.data.test_joints))
        subsets = view_subsets(K)
        for i, views in enumerate(subsets):
            self._tick(f"E4: kNN, ridge and MLP, views {views_label(views)}", i, len(subsets))
            for kind in REGRESSORS:
                s = self.score_regressor(kind, views, noisy)
                self._add(dict(experiment="E4", method=kind, training="multi-view", trained_views=views_label(views),
                               input_views=views_label(views), n_input_views=len(views), noise=self.config.noise.label), **s)
                if len(views) < K:  # only the all-views regressors are used again (E3, E6); a kNN holds its rows
                    self._regressors.pop((kind, tuple(views)), None)
        self._tick("E4", len(subsets), len(subsets))

    # ---------------------------------------------------------------- output
    def frame(self):
        """All rows as a pandas DataFrame (one row per experiment condition and test example)."""
        frames = [pd.DataFrame(r) for r in self.rows]
        df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
        for col in ("experiment", "method", "training", "trained_views", "input_views", "noise"):
            if col in df:
                df[col] = df[col].astype(str)
        return df


@dataclass(frozen=True)
class _BoundViews:
    """The MLP baseline bound to one view subset: ``predict(contours_norm, size)`` like a ViewSubsetRegressor."""

    mlp: ViewDropoutMLP
    views: tuple[int, ...]

    def predict(self, contours_norm: np.ndarray, size: np.ndarray | None = None) -> np.ndarray:
        return self.mlp.predict(contours_norm, self.views, size=size)


@contextmanager
def _quiet_nanmean():
    """Silence 'Mean of empty slice' (an all-NaN row is a legitimate NaN result here)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        yield
