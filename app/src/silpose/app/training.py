"""The work behind ``silpose train``: load a split, optionally select hyperparameters, fit, report.

A held-out part of the train split (``heldout`` fraction, seeded) is kept out of the fit and
scored: mean log-likelihood per sample of the full shape+structure vectors, and the mean joint
error (cm) inferring joints from all modelled views. The saved model is the one fitted on the
remaining part of train.

With ``streaming`` (``silpose train --streaming``) or ``executor="ray"`` the split is never loaded
whole: EM streams over its Parquet shards (``silpose.model.streaming``) and the held-out part is
scored shard by shard; the held-out rows are the same as in memory.

Writes ``<model>.npz`` (:mod:`silpose.model.persistence`) and its training report
``<model>.report.md`` / ``.report.json``, each atomically.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from silpose.model.persistence import save_model
from silpose.model.provenance import manifest_sha256
from silpose.model.selection import select as run_selection, validation_split
from silpose.model.shape_model import (
    DEFAULT_N_COMPONENTS,
    DEFAULT_N_LATENT,
    DEFAULT_NOISE_VARIANCE,
    DEFAULT_STRUCTURE_WEIGHT,
    ShapeStructureModel,
)
from silpose.model.shards import split_global_rows
from silpose.model.streaming import EXECUTORS, DatasetShards
from silpose.shared.atomic import write_text_atomic
from silpose.shared.dataset import load_split, read_shard
from silpose.shared.metrics import pose_error_cm

from .errors import TrainingError


@dataclass
class TrainingResult:
    model_path: Path
    report_md: Path
    report_json: Path
    report: dict = field(default_factory=dict)

    def summary(self) -> str:
        r = self.report
        return (
            f"{self.model_path}: M={r['hyperparameters']['n_components']} q={r['hyperparameters']['n_latent']} "
            f"w={r['hyperparameters']['structure_weight']:g} on {r['n_fit']} samples, "
            f"{r['em']['n_iter']} EM iterations in {r['em']['fit_time_s']:.1f} s; held-out log-likelihood "
            f"{r['heldout']['mean_loglik']:.1f}/sample, joint error {r['heldout']['joint_error_cm']:.2f} cm "
            f"({r['n_heldout']} samples); report {self.report_md}"
        )


def resolve_dataset(preset: str, data_root: Path) -> tuple[Path, str]:
    """(dataset folder, name): an existing folder is used as is, otherwise ``data_root/<preset>``."""
    p = Path(preset)
    if p.is_dir():
        return p, p.resolve().name
    candidate = Path(data_root) / preset
    if candidate.is_dir():
        return candidate, preset
    raise TrainingError(
        f"{candidate}: no dataset folder for preset {preset!r}; generate it first (silpose gen {preset}) "
        f"or pass a dataset folder"
    )


class EMProgress:
    """rich progress display fed by MPPCA's ``callback(iteration, mean_loglik)``."""

    def __init__(self, enabled: bool, max_iter: int, n_init: int):
        self.enabled, self.max_iter, self.n_init = enabled, max_iter, n_init
        self.run = 0
        self.last = 0
        self.curves: list[list[float]] = []
        self._progress = None
        self._task = None

    def __enter__(self):
        if self.enabled:
            self._progress = Progress(TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn(),
                                      transient=False)
            self._progress.__enter__()
        return self

    def __exit__(self, *exc):
        if self._progress is not None:
            self._progress.__exit__(*exc)

    def __call__(self, iteration: int, loglik: float) -> None:
        # MPPCA numbers iterations per run; a jump means another run (em-EM: short runs from each
        # start, then the best one continued), so each contiguous segment gets its own bar.
        if not self.curves or iteration != self.last + 1:
            self.run += 1
            self.curves.append([])
            if self._progress is not None:
                self._task = self._progress.add_task("EM", total=self.max_iter)
        self.curves[-1].append(float(loglik))
        self.last = iteration
        if self._progress is not None:
            self._progress.update(self._task, completed=iteration,
                                  description=f"EM segment {self.run} iteration {iteration:3d}  "
                                              f"log-lik {loglik:,.2f}/sample")


def run_training(
    preset: str,
    *,
    out: Path | None = None,
    select: bool = False,
    n_components: int | None = None,
    n_latent: int | None = None,
    structure_weight: float | None = None,
    noise_variance: float | None = None,
    views: Sequence[int] | None = None,
    max_iter: int = 200,
    n_init: int = 3,
    tol: float = 1e-4,
    seed: int = 0,
    heldout: float = 0.1,
    data_root: Path = Path("data"),
    progress: bool = True,
    grid: dict | None = None,
    streaming: bool = False,
    executor: str = "local",
    workers: int | None = None,
) -> TrainingResult:
    """Fit on ``<dataset>/train`` minus a held-out part; write the model and its report. See module doc.

    ``streaming`` fits out of core (EM streams over the train shards, ``ShapeStructureModel.fit_stream``)
    and scores the held-out part shard by shard; ``executor="ray"`` (implies streaming) runs each
    shard's EM task on Ray with ``workers`` CPUs when it starts a local Ray instance.
    """
    if executor not in EXECUTORS:
        raise TrainingError(f"executor must be 'local' or 'ray', got {executor!r}")
    streaming = bool(streaming) or executor == "ray"
    if streaming and select:
        raise TrainingError("--select fits its grid in memory; run it without --streaming / --executor ray, "
                            "then train the chosen hyperparameters with streaming")
    root, name = resolve_dataset(preset, data_root)
    if streaming:
        plan = DatasetShards.open(root, "train", executor=executor, workers=workers)
        split, metadata, rig = None, plan.metadata, plan.rig
        n, n_views, n_points = sum(plan.shard_rows()), plan.n_rig_views, plan.n_points
    else:
        split = load_split(root, "train", columns=["joints", "contours", "contour_centroid", "contour_scale"])
        metadata, rig = split.metadata, split.rig
        n, n_views, n_points = len(split), split.contours.shape[1], split.contours.shape[2]
    if n < 4:
        raise TrainingError(f"{root}: the train split has {n} samples; at least 4 are needed")
    fit_idx, held_idx = validation_split(n, heldout, seed)
    contours, joints = (None, None) if split is None else (split.contours, split.joints)
    hp = {
        "n_components": DEFAULT_N_COMPONENTS if n_components is None else n_components,
        "n_latent": DEFAULT_N_LATENT if n_latent is None else n_latent,
        "structure_weight": DEFAULT_STRUCTURE_WEIGHT if structure_weight is None else structure_weight,
        "noise_variance": DEFAULT_NOISE_VARIANCE if noise_variance is None else noise_variance,
    }
    selection = None
    if select:
        user = {k: (v,) for k, v in dict(n_components=n_components, n_latent=n_latent,
                                          structure_weight=structure_weight, noise_variance=noise_variance).items()
                if v is not None}
        print(f"model selection on {len(fit_idx)} training samples ...", flush=True)
        selection = run_selection(
            contours[fit_idx], joints[fit_idx], grid={**(grid or {}), **user}, views=views, seed=seed,
            max_iter=min(max_iter, 100), tol=tol, rig=rig,
            progress=(lambda i, k, row: print(f"  fit {i}/{k}: q={row['n_latent']} M={row['n_components']} "
                                              f"w={row['structure_weight']:g} -> {row['val_error_cm']:.2f} cm",
                                              flush=True)) if progress else None,
        )
        print(selection.to_markdown())
        hp = {k: selection.best[k] for k in hp}
    notes = []
    if n_latent is None and not select:
        q_data = max(1, len(fit_idx) // (2 * int(hp["n_components"])))
        if q_data < hp["n_latent"]:  # a small dataset (e.g. smoke) cannot support the default q
            notes.append(f"n_latent lowered from the default {hp['n_latent']} to {q_data} "
                         f"(= fitted samples / (2 M)) for this small dataset")
            hp["n_latent"] = q_data
    max_q = min(len(fit_idx) - 1, n_points * 2 * (len(views) if views else n_views))
    if hp["n_latent"] >= max_q:
        raise TrainingError(f"n_latent = {hp['n_latent']} is too large for {len(fit_idx)} training samples (< {max_q})")
    for note in notes:
        print(f"note: {note}", flush=True)

    with EMProgress(progress, max_iter, n_init) as em:
        model = ShapeStructureModel(
            hp["n_components"], hp["n_latent"], structure_weight=hp["structure_weight"], views=views,
            noise_variance=hp["noise_variance"], tol=tol, max_iter=max_iter, n_init=n_init, random_state=seed,
            callback=em,
        )
        t0 = time.perf_counter()
        if streaming:
            model.fit_stream(root, "train", rows=fit_idx, executor=executor, workers=workers)
        else:
            model.fit(contours[fit_idx], joints[fit_idx], rig=rig)
        wall = time.perf_counter() - t0
    model.callback = None
    model.dataset_info_ = _dataset_info(root, name, metadata, n, len(fit_idx), len(held_idx))
    mode = {"streaming": streaming, "executor": executor if streaming else "in-memory",
            "n_shards": len(plan.paths) if streaming else None}
    model.training_config_ = {"command": "silpose train", "heldout_fraction": heldout, "seed": seed,
                              "select": bool(select), "selection_best": None if selection is None else selection.best,
                              "mode": mode}
    if streaming:
        held_ll, held_err, held_contours = _heldout_streaming(model, plan, held_idx)
    else:
        held_contours = contours[held_idx]
        held_ll = model.score_samples(held_contours, joints[held_idx])
        held_err = pose_error_cm(model.infer(held_contours).joints, joints[held_idx])
    model.calibrate_plausibility(held_contours, seed=seed)  # stored in the model file (silpose.model.plausibility)

    out = Path(out) if out is not None else Path("models") / f"{name}.npz"
    save_model(out, model)
    mix = model.mixture_
    report = {
        "model": str(out),
        "dataset": model.dataset_info_,
        "n_fit": int(len(fit_idx)),
        "n_heldout": int(len(held_idx)),
        "mode": mode,
        "hyperparameters": model.get_params(),
        "em": {
            "n_iter": int(mix.n_iter_),
            "converged": bool(mix.converged_),
            "mean_loglik": float(mix.lower_bound_),
            "loglik_curve": [float(v) for v in mix.lower_bounds_],
            "all_segments": em.curves,
            "fit_time_s": float(wall),
        },
        "heldout": {
            "mean_loglik": float(np.mean(held_ll)),
            "joint_error_cm": float(np.mean(held_err)),
            "joint_error_median_cm": float(np.median(held_err)),
        },
        "selection": None if selection is None else selection.to_dict(),
        "notes": notes,
    }
    report_json = out.with_suffix(".report.json")
    report_md = out.with_suffix(".report.md")
    write_text_atomic(report_json, json.dumps(report, indent=2))
    write_text_atomic(report_md, report_markdown(report, selection))
    return TrainingResult(out, report_md, report_json, report)


def _heldout_streaming(model, plan, held_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(log-likelihood (H,), joint error cm (H,), contours (H, K, n, 2) px) of the held-out rows, reading one
    shard at a time."""
    lls, errs, conts = [], [], []
    for path, rows in zip(plan.paths, split_global_rows(np.asarray(held_idx), plan.shard_rows())):
        if rows.size == 0:
            continue
        shard = read_shard(path, columns=["joints", "contours"])
        c, j = shard.contours[rows], shard.joints[rows]
        del shard
        lls.append(model.score_samples(c, j))
        errs.append(pose_error_cm(model.infer(c).joints, j))
        conts.append(np.asarray(c, dtype=np.float64))
    return np.concatenate(lls), np.concatenate(errs), np.concatenate(conts)


def _dataset_info(root: Path, name: str, metadata: dict, n_samples: int, n_fit: int, n_held: int) -> dict:
    """What the model file records about its training data (``dataset_info_``)."""
    return {
        "name": name,
        "root": str(root),
        "split": "train",
        "n_samples": int(n_samples),
        "n_fit": n_fit,
        "n_heldout": n_held,
        "manifest_sha256": manifest_sha256(root),
        "config_name": (metadata.get("config") or {}).get("name"),
        "generator_config": metadata.get("config"),
    }


def report_markdown(r: dict, selection) -> str:
    """The training report as Markdown (from the report dict ``r`` and the selection result or None)."""
    hp, em, held = r["hyperparameters"], r["em"], r["heldout"]
    curve = em["loglik_curve"]
    shown = curve if len(curve) <= 12 else curve[:6] + curve[-6:]
    lines = [
        f"# Training report: {Path(r['model']).name}",
        "",
        f"- data: `{r['dataset']['root']}` train split, {r['n_fit']} samples fitted, {r['n_heldout']} held out "
        f"(manifest sha256 `{r['dataset']['manifest_sha256']}`)",
        f"- model: M = {hp['n_components']} components, q = {hp['n_latent']}, structure weight "
        f"{hp['structure_weight']:g}, views {hp['views'] if hp['views'] is not None else 'all'}, "
        f"inference noise s² = {hp['noise_variance']:g}",
        f"- EM: {em['n_iter']} iterations ({'converged' if em['converged'] else 'NOT converged'}, tol {hp['tol']:g}), "
        f"best of {hp['n_init']} runs, {em['fit_time_s']:.1f} s in total"
        + (f"; streamed over {r['mode']['n_shards']} shards ({r['mode']['executor']})" if r.get("mode", {}).get("streaming")
           else "; in memory"),
        f"- training mean log-likelihood: {em['mean_loglik']:.2f} nats/sample",
        f"- held-out mean log-likelihood: {held['mean_loglik']:.2f} nats/sample",
        f"- held-out joint error (all views observed): mean {held['joint_error_cm']:.2f} cm, "
        f"median {held['joint_error_median_cm']:.2f} cm",
        *[f"- note: {n}" for n in r.get("notes", [])],
        "",
        "## Log-likelihood curve (kept run, nats/sample)",
        "",
        "| iteration | mean log-likelihood |",
        "|---:|---:|",
    ]
    idx = list(range(1, len(curve) + 1))
    shown_idx = idx if len(curve) <= 12 else idx[:6] + idx[-6:]
    lines += [f"| {i} | {v:.4f} |" for i, v in zip(shown_idx, shown)]
    if selection is not None:
        lines += ["", f"## Model selection ({selection.n_train} fit / {selection.n_val} validation samples)", "",
                  selection.to_markdown()]
    return "\n".join(lines) + "\n"
