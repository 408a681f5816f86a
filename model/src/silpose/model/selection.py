"""Model selection: q, M, the structure weight and the observation-noise variance on validation data.

A validation split is carved from the *training* data (a seeded random permutation; the test
split is never touched). For every (n_latent q, n_components M, structure_weight w) in a small grid a
:class:`ShapeStructureModel` is fitted on the rest; each fitted model is then scored for every
observation-noise variance s^2 in the grid (inference only, no refit) by the paper's pose error
(:func:`silpose.shared.metrics.pose_error_cm`: mean Euclidean distance over the 19 root-relative
joints in cm; docs/conventions.md, "Evaluation protocol") of the mixture posterior mean on the
validation contours, with all modelled views observed. The lowest error wins.
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

from .shape_model import ShapeStructureModel

#: The default grid (12 fits): centred on the region the 2026-11-22 selection on the `default` preset
#: found best (see the defaults in shape_model.py); small enough for that preset on 2 cores (~5 min).
DEFAULT_GRID: dict[str, tuple] = {
    "n_latent": (30, 40),
    "n_components": (10, 20),
    "structure_weight": (10.0, 30.0, 100.0),
    "noise_variance": (0.01, 0.03, 0.1),
}
COLUMNS = ("n_latent", "n_components", "structure_weight", "noise_variance", "val_error_cm", "val_error_best_cm",
           "val_loglik", "n_iter", "fit_time_s")


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
    """A Markdown table of the grid, sorted by validation error; the best row is marked with '*'."""
    head = "| | q | M | w | s² | val error (cm) | best-comp. error (cm) | val log-lik | EM iters | fit (s) |"
    lines = [head, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in sorted(rows, key=lambda r: r["val_error_cm"]):
        mark = "*" if best is not None and all(r[k] == best[k] for k in COLUMNS[:4]) else ""
        lines.append(
            f"| {mark} | {r['n_latent']} | {r['n_components']} | {r['structure_weight']:g} | {r['noise_variance']:g} "
            f"| {r['val_error_cm']:.2f} | {r['val_error_best_cm']:.2f} | {r['val_loglik']:.1f} | {r['n_iter']} "
            f"| {r['fit_time_s']:.1f} |"
        )
    return "\n".join(lines) + "\n"


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
    tol: float = 1e-4,
    rig=None,
    progress: Callable[[int, int, dict], None] | None = None,
) -> SelectionResult:
    """Grid search on a validation split carved from the training data.

    Args:
        contours_px: (N, K, n, 2) training contours in pixels (all rig views).
        joints: (N, 19, 3) training joints, metres.
        grid: dict with keys ``n_latent``, ``n_components``, ``structure_weight``, ``noise_variance`` (sequences);
            missing keys take ``DEFAULT_GRID``'s values.
        views: modelled views (None = all).
        val_fraction, seed: the validation split (``validation_split``).
        n_init, max_iter, tol: EM settings of each fit (smaller than a final fit's, to keep the search cheap).
        progress: called as ``progress(i, n_fits, row)`` after each fit.
    Returns:
        :class:`SelectionResult` (rows for every grid point, the best one).
    """
    g = {k: tuple(v) for k, v in {**DEFAULT_GRID, **(grid or {})}.items()}
    unknown = set(g) - set(DEFAULT_GRID)
    if unknown:
        raise ValueError(f"unknown grid keys {sorted(unknown)}; expected {sorted(DEFAULT_GRID)}")
    for k, v in g.items():
        if not v:
            raise ValueError(f"grid[{k!r}] is empty")
    contours_px = np.asarray(contours_px)
    joints = np.asarray(joints)
    tr, va = validation_split(len(joints), val_fraction, seed)
    fits = list(itertools.product(g["n_latent"], g["n_components"], g["structure_weight"]))
    rows: list[dict] = []
    for i, (q, m, w) in enumerate(fits):
        model = ShapeStructureModel(
            n_components=int(m), n_latent=int(q), structure_weight=float(w), views=views,
            n_init=n_init, max_iter=max_iter, tol=tol, random_state=seed,
        )
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # ConvergenceWarning at the reduced max_iter: recorded as n_iter
            model.fit(contours_px[tr], joints[tr], rig=rig)
        fit_time = time.perf_counter() - t0
        val_ll = float(np.mean(model.score_samples(contours_px[va], joints[va])))
        for s2 in g["noise_variance"]:
            res = model.infer(contours_px[va], noise_variance=float(s2))
            row = {
                "n_latent": int(q),
                "n_components": int(m),
                "structure_weight": float(w),
                "noise_variance": float(s2),
                "val_error_cm": float(pose_error_cm(res.joints, joints[va]).mean()),
                "val_error_best_cm": float(pose_error_cm(res.joints_best, joints[va]).mean()),
                "val_loglik": val_ll,
                "n_iter": int(model.mixture_.n_iter_),
                "fit_time_s": fit_time,
            }
            rows.append(row)
        if progress is not None:
            progress(i + 1, len(fits), rows[-1])
    finite = [r for r in rows if math.isfinite(r["val_error_cm"])]
    if not finite:
        raise RuntimeError("model selection: every grid point gave a non-finite validation error")
    best = min(finite, key=lambda r: (r["val_error_cm"], r["n_latent"], r["n_components"]))
    return SelectionResult(rows=rows, best=best, grid=g, n_train=int(tr.size), n_val=int(va.size))
