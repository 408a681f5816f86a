"""Model selection: q, M, the structure weight and the observation-noise variance on validation data.

A validation split is carved from the *training* data (a seeded random permutation; the test
split is never touched). With ``groups`` (e.g. the motion clip or subject of each row) the split
holds out whole groups (:func:`validation_split_groups`), so the validation error is a held-out-group
error, as the test split's held-out subjects need. For every (n_latent q, n_components M, structure_weight w) in a small grid
a :class:`ShapeStructureModel` is fitted on the rest and scored on the validation samples by

- the **joint error** (:func:`silpose.shared.metrics.pose_error_cm`: mean Euclidean distance over
  the 19 root-relative joints in cm; docs/conventions.md, "Evaluation protocol") of the mixture
  posterior mean, given every modelled view (``val_error_cm``) and given each view alone (mean
  over the views, ``val_error_1view_cm``); the selection score ``val_score_cm`` is their mean.
  The validation contours get the ragged-outline noise of :mod:`silpose.model.augment` (its
  default :class:`~silpose.model.augment.Roughness`, a stream of its own), so the observation-noise
  variance s^2 is chosen for imperfect inputs; each s^2 of the grid is scored on the same fit
  (inference only, no refit);
- the **held-out log-likelihood** ``val_loglik``: the mean log density of the validation samples'
  full shape+structure vectors, in nats per sample, expressed for structure weight 1 (plus
  ``n_structure * log w``, the Jacobian of the weighting) so that fits with different w compare;
  ``train_loglik`` is the same on the fitted rows, and ``loglik_gap`` their difference;
- whether the fit is a **real EM fit** (``real_em``): for M > 1, more than one EM iteration and the
  training log-likelihood rising by more than ``tol`` from its start (a fit whose EM never moves
  is its k-means partition with one PCA per cluster: see ``silpose.model.mppca``). For M = 1 the
  closed-form start is already the maximum-likelihood PPCA, so M = 1 fits count as real.

The choice (:func:`choose`): among real EM fits (all fits if none is real, flagged), each fit at its
best s^2, keep those not dominated in (score, held-out log-likelihood) by another fit; among these,
the fits whose score is within ``error_tolerance`` (relative) of the best score "match the error",
and the one with the fewest free parameters wins (then the higher held-out log-likelihood).
"""

from __future__ import annotations

import itertools
import math
import time
import warnings
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from silpose.shared.metrics import pose_error_cm
from silpose.shared.seeds import VALIDATION_STREAM, derive_rng

from .augment import Roughness, roughen_contours, training_rows
from .shape_model import ShapeStructureModel

#: The default grid (18 fits, 3 s^2 each): around the region the 2026-11 selections on the `default`
#: preset found best, and M 40 / 60 for larger data such as the paper preset's (see the defaults in
#: shape_model.py; on small data those fits stay at their k-means start and are not chosen).
DEFAULT_GRID: dict[str, tuple] = {
    "n_latent": (20, 30, 40),
    "n_components": (5, 10, 15, 20, 40, 60),
    "structure_weight": (30.0,),
    "noise_variance": (0.01, 0.03, 0.1),
}
#: A grid for varied motion (the ``motions`` preset): M in the hundreds, fitted with the MPPCA's sparse E-step
#: (``silpose.model.mppca``, automatic from M 64 on).
LARGE_GRID: dict[str, tuple] = {
    "n_latent": (20, 30),
    "n_components": (50, 100, 200),
    "structure_weight": (30.0,),
    "noise_variance": (0.03,),
}
#: Relative score margin within which a smaller model "matches the error" (:func:`choose`).
DEFAULT_ERROR_TOLERANCE = 0.02
#: Seed offset of the validation inputs' roughness stream (sample ids are the validation rows' indices).
VALIDATION_ROUGHNESS_SEED = 1
COLUMNS = ("n_latent", "n_components", "structure_weight", "noise_variance", "val_error_cm", "val_error_1view_cm",
           "val_score_cm", "val_error_best_cm", "val_loglik", "train_loglik", "loglik_gap", "em_gain", "n_iter",
           "real_em", "n_parameters", "fit_time_s")
_KEY = COLUMNS[:4]


def validation_split(n_samples: int, fraction: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(train indices, validation indices), a seeded random split; the validation part has >= 1 sample.

    The permutation comes from ``derive_rng(seed, VALIDATION_STREAM)`` (``silpose.shared.seeds``).
    """
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"validation fraction must be in (0, 1), got {fraction}")
    if n_samples < 2:
        raise ValueError(f"need at least 2 samples to carve a validation split, got {n_samples}")
    perm = derive_rng(seed, VALIDATION_STREAM).permutation(n_samples)
    n_val = min(max(1, int(round(fraction * n_samples))), n_samples - 1)
    return np.sort(perm[n_val:]), np.sort(perm[:n_val])


def validation_split_groups(groups: np.ndarray, fraction: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(train indices, validation indices) holding out whole groups: a seeded permutation of the distinct
    ``groups`` (N,) (``derive_rng(seed, VALIDATION_STREAM)``), groups taken into validation until it has
    about ``fraction`` of the rows; both parts non-empty, no group in both."""
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"validation fraction must be in (0, 1), got {fraction}")
    groups = np.asarray(groups)
    uniq, inverse, counts = np.unique(groups, return_inverse=True, return_counts=True)
    if len(uniq) < 2:
        raise ValueError(f"need at least 2 groups to carve a validation split, got {len(uniq)}")
    order = derive_rng(seed, VALIDATION_STREAM).permutation(len(uniq))
    taken = np.cumsum(counts[order]) <= max(counts[order[0]], fraction * len(groups))
    taken[-1] = False  # keep at least one group for training
    val_groups = np.zeros(len(uniq), bool)
    val_groups[order[taken]] = True
    is_val = val_groups[inverse.reshape(-1)]
    return np.flatnonzero(~is_val), np.flatnonzero(is_val)


def unit_weight_loglik(model: ShapeStructureModel, values: np.ndarray) -> np.ndarray:
    """Log densities (nats) of shape vectors scored by ``model``, expressed for structure weight 1.

    The structure block is ``w s``, so ``log p(s) = log p_w(w s) + n_structure log w`` (the Jacobian);
    ``values`` are ``model.mixture_`` log densities (any shape). Returns them corrected.
    """
    layout = model.fitted_layout()
    return np.asarray(values, dtype=np.float64) + layout.structure_dim * math.log(layout.structure_weight)


def is_real_em(mixture, tol: float) -> bool:
    """True when EM moved (module doc): M = 1, or more than one iteration and a gain above ``tol``; for
    pooled fits (``runs_``, :func:`silpose.model.mppca.pool_mixtures`) when every fit's EM moved."""
    runs = getattr(mixture, "runs_", None)
    if runs:
        return all(r["n_components"] == 1 or (r["n_iter"] > 1 and r["final_bound"] - r["initial_bound"] > tol)
                   for r in runs)
    if mixture.weights_.shape[0] == 1:
        return True
    gain = mixture.lower_bounds_[-1] - getattr(mixture, "initial_bound_", mixture.lower_bounds_[-1])
    return bool(mixture.n_iter_ > 1 and gain > tol)


def view_errors(model: ShapeStructureModel, contours_px: np.ndarray, joints: np.ndarray,
                noise_variance: float | None = None) -> dict[str, float]:
    """Mean joint errors (cm) given every modelled view (``all``) and each modelled view alone
    (``one``: the mean over views; NaN for a single-view model) and of the best component (``best``)."""
    res = model.infer(contours_px, noise_variance=noise_variance)
    views = model.fitted_layout().views
    out = {"all": float(pose_error_cm(res.joints, joints).mean()),
           "best": float(pose_error_cm(res.joints_best, joints).mean()), "one": float("nan")}
    if len(views) > 1:
        n_rig = contours_px.shape[1]
        errs = []
        for v in views:
            present = np.zeros((len(joints), n_rig), dtype=bool)
            present[:, v] = True
            one = model.infer(contours_px, views_present=present, noise_variance=noise_variance)
            errs.append(pose_error_cm(one.joints, joints).mean())
        out["one"] = float(np.mean(errs))
    return out


@dataclass
class SelectionResult:
    """rows: one dict per grid point (keys ``COLUMNS``); best: the winning row; grid: the grid searched."""

    rows: list[dict]
    best: dict
    grid: dict
    n_train: int
    n_val: int
    extra: dict = field(default_factory=dict)

    def to_markdown(self) -> str:
        return results_markdown(self.rows, best=self.best)

    def to_dict(self) -> dict:
        return {"rows": self.rows, "best": self.best, "grid": {k: list(v) for k, v in self.grid.items()},
                "n_train": self.n_train, "n_val": self.n_val, **self.extra}


def results_markdown(rows: Sequence[dict], best: dict | None = None) -> str:
    """A Markdown table of the grid, sorted by validation score; the best row is marked with '*'."""
    head = ("| | q | M | w | s² | val error, all views (cm) | 1 view (cm) | score (cm) | val log-lik | train log-lik "
            "| EM iters | real EM | parameters | fit (s) |")
    lines = [head, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|"]
    for r in sorted(rows, key=lambda r: r["val_score_cm"]):
        mark = "*" if best is not None and all(r[k] == best[k] for k in _KEY) else ""
        lines.append(
            f"| {mark} | {r['n_latent']} | {r['n_components']} | {r['structure_weight']:g} | {r['noise_variance']:g} "
            f"| {r['val_error_cm']:.2f} | {r['val_error_1view_cm']:.2f} | {r['val_score_cm']:.2f} | {r['val_loglik']:.1f} "
            f"| {r['train_loglik']:.1f} | {r['n_iter']} | {'yes' if r['real_em'] else 'no'} | {r['n_parameters']:,} "
            f"| {r['fit_time_s']:.1f} |"
        )
    return "\n".join(lines) + "\n"


def choose(rows: Sequence[dict], error_tolerance: float = DEFAULT_ERROR_TOLERANCE) -> tuple[dict, dict]:
    """The winning row of a grid (module doc) and a dict describing the choice.

    Returns (best row, {"pool": "real EM fits" | "all fits (no real EM fit)", "pareto": [...],
    "matching": [...]}) where the lists hold the (q, M, w, s^2) keys of the Pareto set and of the
    fits matching the best score.
    """
    finite = [r for r in rows if math.isfinite(r["val_score_cm"]) and math.isfinite(r["val_loglik"])]
    if not finite:
        raise RuntimeError("model selection: every grid point gave a non-finite validation score")
    real = [r for r in finite if r["real_em"]]
    pool = real or finite
    per_fit: dict[tuple, dict] = {}
    for r in pool:  # each fit at its best s^2
        k = (r["n_latent"], r["n_components"], r["structure_weight"])
        if k not in per_fit or r["val_score_cm"] < per_fit[k]["val_score_cm"]:
            per_fit[k] = r
    fits = list(per_fit.values())
    pareto = [r for r in fits if not any(
        o["val_score_cm"] <= r["val_score_cm"] and o["val_loglik"] >= r["val_loglik"]
        and (o["val_score_cm"] < r["val_score_cm"] or o["val_loglik"] > r["val_loglik"]) for o in fits)]
    best_score = min(r["val_score_cm"] for r in pareto)
    matching = [r for r in pareto if r["val_score_cm"] <= best_score * (1.0 + error_tolerance)]
    best = min(matching, key=lambda r: (r["n_parameters"], -r["val_loglik"], r["val_score_cm"]))
    keys = lambda rs: [[r[k] for k in _KEY] for r in rs]  # noqa: E731
    return best, {"pool": "real EM fits" if real else "all fits (no real EM fit)", "pareto": keys(pareto),
                  "matching": keys(matching), "error_tolerance": error_tolerance}


def select(
    contours_px: np.ndarray,
    joints: np.ndarray,
    *,
    grid: dict | None = None,
    views: Sequence[int] | None = None,
    val_fraction: float = 0.2,
    seed: int = 0,
    n_init: int = 1,
    max_iter: int = 100,
    tol: float = 0.1,
    rig=None,
    roughness: Roughness | None = None,
    mirrors: tuple = (),
    noise_dof: bool = True,
    error_tolerance: float = DEFAULT_ERROR_TOLERANCE,
    progress: Callable[[int, int, dict], None] | None = None,
    groups: np.ndarray | None = None,
) -> SelectionResult:
    """Grid search on a validation split carved from the training data (module doc).

    Args:
        contours_px: (N, K, n, 2) training contours in pixels (all rig views).
        joints: (N, 19, 3) training joints, metres.
        grid: dict with keys ``n_latent``, ``n_components``, ``structure_weight``, ``noise_variance`` (sequences);
            missing keys take ``DEFAULT_GRID``'s values.
        views: modelled views (None = all).
        val_fraction, seed: the validation split (``validation_split``).
        n_init, max_iter, tol: EM settings of each fit (smaller than a final fit's, to keep the search cheap).
        roughness: training augmentation (``silpose.model.augment``) applied to the fitted rows as in
            ``silpose train --roughness``; None = none. The validation inputs are roughened either way.
        mirrors: rig symmetries (``silpose.shared.rig_symmetry.RigMirror``) whose mirrored people are added to
            the fitted rows (``silpose.model.augment.training_rows``; needs ``rig``); never to the validation rows.
        noise_dof: the fits' ``noise_dof`` (``ShapeStructureModel``).
        error_tolerance: relative score margin of :func:`choose`.
        progress: called as ``progress(i, n_fits, row)`` after each fit.
        groups: optional (N,) group of each sample (clip, subject): the validation split holds out whole
            groups (:func:`validation_split_groups`); None = a random split of the samples.
    Returns:
        :class:`SelectionResult` (rows for every grid point, the best one; ``extra["choice"]`` says how).
    """
    g = {k: tuple(v) for k, v in {**DEFAULT_GRID, **(grid or {})}.items()}
    unknown = set(g) - set(DEFAULT_GRID)
    if unknown:
        raise ValueError(f"unknown grid keys {sorted(unknown)}; expected {sorted(DEFAULT_GRID)}")
    for k, v in g.items():
        if not v:
            raise ValueError(f"grid[{k!r}] is empty")
    contours_px = np.asarray(contours_px, dtype=np.float64)
    joints = np.asarray(joints)
    if groups is None:
        tr, va = validation_split(len(joints), val_fraction, seed)
    else:
        if len(groups) != len(joints):
            raise ValueError(f"groups has {len(groups)} entries for {len(joints)} samples")
        tr, va = validation_split_groups(groups, val_fraction, seed)
    c_fit, j_fit = contours_px[tr], joints[tr]
    if roughness is not None or mirrors:
        c_fit, j_fit = training_rows(c_fit, j_fit, tr, rig=rig, mirrors=tuple(mirrors), roughness=roughness, seed=seed)
    c_val = roughen_contours(contours_px[va], Roughness(), seed + VALIDATION_ROUGHNESS_SEED, va)
    fits = list(itertools.product(g["n_latent"], g["n_components"], g["structure_weight"]))
    rows: list[dict] = []
    for i, (q, m, w) in enumerate(fits):
        model = ShapeStructureModel(
            n_components=int(m), n_latent=int(q), structure_weight=float(w), views=views,
            n_init=n_init, max_iter=max_iter, tol=tol, random_state=seed, noise_dof=noise_dof,
        )
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # ConvergenceWarning at the reduced max_iter: recorded as n_iter
            model.fit(c_fit, j_fit, rig=rig)
        fit_time = time.perf_counter() - t0
        mix = model.mixture_
        val_ll = float(np.mean(unit_weight_loglik(model, model.score_samples(contours_px[va], joints[va]))))
        train_ll = float(unit_weight_loglik(model, mix.lower_bound_))
        for s2 in g["noise_variance"]:
            err = view_errors(model, c_val, joints[va], float(s2))
            one = err["one"] if math.isfinite(err["one"]) else err["all"]
            rows.append({
                "n_latent": int(q),
                "n_components": int(m),
                "structure_weight": float(w),
                "noise_variance": float(s2),
                "val_error_cm": err["all"],
                "val_error_1view_cm": one,
                "val_score_cm": 0.5 * (err["all"] + one),
                "val_error_best_cm": err["best"],
                "val_loglik": val_ll,
                "train_loglik": train_ll,
                "loglik_gap": train_ll - val_ll,
                "em_gain": float(mix.lower_bounds_[-1] - mix.initial_bound_),
                "n_iter": int(mix.n_iter_),
                "real_em": is_real_em(mix, tol),
                "n_parameters": int(mix.n_parameters()),
                "fit_time_s": fit_time,
            })
        if progress is not None:
            progress(i + 1, len(fits), rows[-1])
    best, how = choose(rows, error_tolerance)
    return SelectionResult(rows=rows, best=best, grid=g, n_train=int(tr.size), n_val=int(va.size),
                           extra={"choice": how, "roughness": None if roughness is None else roughness.to_dict(),
                                  "mirrors": [m.to_dict() for m in mirrors]})

