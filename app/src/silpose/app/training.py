"""The work behind ``silpose train``: load a split, optionally select hyperparameters, fit, report.

A held-out part of the train split (``heldout`` fraction, seeded; whole clips on a dataset posed
from motion-capture clips, :mod:`silpose.app.heldout`) is kept out of the fit and scored: mean
log-likelihood per sample of the full shape+structure vectors (beside the same on the
fitted rows, both for structure weight 1: ``silpose.model.selection.unit_weight_loglik``), and the
mean joint error (cm) inferring joints from all modelled views and from each view alone. The
saved model is the one fitted on the remaining part of train. The report says whether EM moved
from its k-means start ("real EM", ``silpose.model.selection.is_real_em``) and how many rows each
component has per latent dimension.

``roughness`` (``silpose train --roughness PX``) adds ragged-outline copies of the fitted rows
(``silpose.model.augment``), a training augmentation for imperfect segmentations. ``mirror``
(``silpose train --mirror``) adds the mirrored person of every fitted row when the rig is
mirror-symmetric (``silpose.shared.rig_symmetry``; the paper's rig is, real calibrations are not).

With ``streaming`` (``silpose train --streaming``) or ``executor="ray"`` the split is never loaded
whole: EM streams over its Parquet shards (``silpose.model.streaming``) and the held-out part is
scored shard by shard; the held-out rows are the same as in memory.

A dataset whose config has a ``[train]`` table (``silpose.datagen.config``: ``components``, ``latent``,
``fits``) is fitted with those values unless the command line gives its own (:func:`dataset_training`); the
``default`` preset pools 5 fits of M 25, q 40 (``configs/default.toml`` says why).

Writes ``<model>.npz`` (:mod:`silpose.model.persistence`) and its training report
``<model>.report.md`` / ``.report.json``, each atomically.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
import pyarrow as pa
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from silpose.model.augment import Roughness, training_rows
from silpose.model.defaults import (
    DEFAULT_N_COMPONENTS,
    DEFAULT_N_LATENT,
    DEFAULT_NOISE_VARIANCE,
    DEFAULT_STRUCTURE_WEIGHT,
)
from silpose.model.mixing import calibrate_mixing
from silpose.model.persistence import is_model_file, save_model
from silpose.model.selection import is_real_em, unit_weight_loglik, view_errors
from silpose.model.selection import select as run_selection
from silpose.model.shape_model import ShapeStructureModel

#: Samples per component per latent dimension below which EM does not move from its k-means start
#: (every row is far likelier under its own component; docs/conventions.md, "Model"). Measured on the
#: default preset (1,440-1,800 fitted samples): EM froze at 2.3-4.5 samples per component per latent
#: dimension (M 10-20, q 30-40 but M 20 q 20 moved at 4.5) and moved at 6 and above.
MIN_ROWS_PER_LATENT = 6
#: The smallest M :func:`supported_size` lowers the default to before lowering q.
MIN_DEFAULT_COMPONENTS = 10

#: ``roughness="auto"`` (the default) adds one ragged copy of every fitted sample (1 px, ``Roughness()``) when
#: at most this many samples are fitted, and none above (the copies double the features in memory: the
#: paper preset's fit would pass 1 GB). Measured on the default preset (M 10, q 30, standard test noise):
#: 4 views 3.83 -> 3.69 cm, 1 view 10.40 -> 9.60 cm; replacing the samples by ragged ones (copies 0) gains nothing.
AUTO_ROUGHNESS_MAX_SAMPLES = 5000

#: ``silpose train``'s EM settings: a run stops when the mean log-likelihood gains less than DEFAULT_TOL
#: nats per sample in an iteration (6e-5 nats per feature for d = 1,657). Measured on the paper preset
#: (18,000 samples, M 20, q 40): EM gains 14, 3.5, 1.5 nats in its first iterations and < 0.1 from the
#: 10th on, while the held-out joint error (2.58 cm) and log-likelihood (2,789 nats) stop changing after
#: the 2nd; the former tol of 1e-4 ran 200 iterations without converging. One start (n_init 1): with
#: hard responsibilities the em-EM restarts cost 15 iterations and kept the same start in our runs.
DEFAULT_TOL = 0.1
DEFAULT_MAX_ITER = 200
DEFAULT_N_INIT = 1

#: ``mirror="auto"`` (the default) adds the mirrored people of the rig's symmetries while the fitted samples
#: and their mirrors stay within this many (each mirror adds a copy of the features in memory, and the
#: paper preset's 18,000 samples fill its 1 GB budget). The default preset (1,800 fitted samples, one
#: symmetry) gets its mirrors: 4 views on 200 held-out walkers, robust, cm, clean 3.68 -> 2.77 and standard
#: noise 4.55 -> 3.82 (``silpose.model.augment``, "Mirrored people").
AUTO_MIRROR_MAX_ROWS = 10_000
MIRROR_MODES = ("auto", "on", "off")
#: A dataset config's ``[train]`` fields (``silpose.datagen.config.TRAIN_KEYS``; read from the stored config, so
#: this package does not import the generator)
TRAIN_FIELDS = ("components", "latent", "fits", "structure_weight")
#: the [train] fields that are numbers > 0, not counts
TRAIN_FLOAT_FIELDS = ("structure_weight",)
from silpose.model.shards import split_global_rows
from silpose.model.streaming import EXECUTORS, DatasetShards
from silpose.shared.atomic import write_text_atomic
from silpose.shared.dataset import DatasetError, list_shards, load_split, read_shard
from silpose.shared.memory import peak_rss_bytes, release_freed_memory
from silpose.shared.metrics import pose_error_cm
from silpose.shared.output_dir import claim_files
from silpose.shared.rig_symmetry import RigMirror, rig_mirrors
from silpose.shared.version import silpose_version

from .errors import TrainingError
from .heldout import clip_groups, heldout_split


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
            f"{r['em']['n_iter']} EM iterations ({'real EM' if r['em']['real_em'] else 'EM did not move'}) in "
            f"{r['em']['fit_time_s']:.1f} s; log-likelihood train {r['em']['train_loglik']:.1f} / held-out "
            f"{r['heldout']['mean_loglik']:.1f} per sample, held-out joint error {r['heldout']['joint_error_cm']:.2f} cm "
            f"({r['n_heldout']} samples); report {self.report_md}"
        )


def supported_size(n_fit: int, m: int, q: int, *, fixed_m: bool = False, fixed_q: bool = False) -> tuple[int, int]:
    """(M, q) the ``n_fit`` fitted samples support: ``n_fit >= MIN_ROWS_PER_LATENT * M * q``.

    Lowers what the user did not fix: M first (not below ``MIN_DEFAULT_COMPONENTS``), then q (>= 1);
    both fixed: unchanged. The default preset's 1,800 samples give M 10, q 30 (what model selection
    chose among the fits whose EM moved); the paper preset's 18,000 keep the defaults M 60, q 40.
    """
    r = MIN_ROWS_PER_LATENT
    if n_fit >= r * m * q:
        return m, q
    if not fixed_m:
        supported = n_fit // (r * q)
        m = max(1, supported) if fixed_q else min(m, max(MIN_DEFAULT_COMPONENTS, supported))
    if not fixed_q and n_fit < r * m * q:
        q = max(1, n_fit // (r * m))
    return m, q


def dataset_training(metadata: dict, root: Path) -> dict:
    """The dataset's ``[train]`` settings (``silpose.datagen.config.TRAIN_KEYS``: components, latent, fits,
    structure_weight), as stored in its config: ``{field: int >= 1}`` (``structure_weight``: float > 0), ``{}`` for
    a dataset without them. A malformed entry is a one-line TrainingError naming the dataset and the field."""
    train = (metadata.get("config") or {}).get("train")
    if train is None:
        return {}
    if not isinstance(train, dict):
        raise TrainingError(f"{root}: field 'config.train' must be a table, got {type(train).__name__}")
    out = {}
    for key, value in train.items():
        if key not in TRAIN_FIELDS:
            raise TrainingError(f"{root}: field 'config.train.{key}': unknown; known: {', '.join(TRAIN_FIELDS)}")
        if key in TRAIN_FLOAT_FIELDS:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < float(value) < float("inf"):
                raise TrainingError(f"{root}: field 'config.train.{key}' must be a number > 0, got {value!r}")
            out[key] = float(value)
            continue
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise TrainingError(f"{root}: field 'config.train.{key}' must be an integer >= 1, got {value!r}")
        out[key] = value
    return out


def resolve_dataset(preset: str, data_root: Path) -> tuple[Path, str]:
    """(dataset folder, name): an existing folder is used as is, otherwise ``data_root/<preset>``."""
    p = Path(preset)
    if p.is_dir():
        return p, p.resolve().name
    if p.exists() or p.is_absolute() or "/" in preset or preset.startswith("."):  # a path, not a preset name
        raise TrainingError(f"{p}: no such dataset folder" if not p.exists() else f"{p}: not a dataset folder")
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
    max_iter: int = DEFAULT_MAX_ITER,
    n_init: int = DEFAULT_N_INIT,
    n_fits: int | None = None,
    tol: float = DEFAULT_TOL,
    seed: int = 0,
    heldout: float = 0.1,
    data_root: Path = Path("data"),
    progress: bool = True,
    grid: dict | None = None,
    streaming: bool = False,
    executor: str = "local",
    workers: int | None = None,
    roughness: Roughness | None | str = "auto",
    mirror: str = "auto",
) -> TrainingResult:
    """Fit on ``<dataset>/train`` minus a held-out part; write the model and its report. See module doc.

    ``roughness``: a :class:`~silpose.model.augment.Roughness`, None (off) or ``"auto"`` (one ragged copy per
    sample up to ``AUTO_ROUGHNESS_MAX_SAMPLES`` fitted samples, off above and when streaming).
    ``streaming`` fits out of core (EM streams over the train shards, ``ShapeStructureModel.fit_stream``)
    and scores the held-out part shard by shard; ``executor="ray"`` (implies streaming) runs each
    shard's EM task on Ray with ``workers`` CPUs when it starts a local Ray instance.
    ``n_fits`` > 1 pools that many EM fits from seeds ``seed``, ``seed + 1``, ... into one mixture
    (``ShapeStructureModel(n_fits=...)``; in memory only); None: the dataset's ``[train] fits``, else 1.
    ``n_components`` / ``n_latent`` None: the dataset's ``[train]`` values, else the defaults lowered for small data
    (:func:`supported_size`); with ``select``, the dataset's ``[train]`` is not used.
    ``mirror``: "auto" (the rig's mirror symmetries, as many as keep the fitted samples and their mirrors
    within ``AUTO_MIRROR_MAX_ROWS``; none when streaming), "on" (all of them; an error if the rig has
    none) or "off". ``supported_size`` counts the mirrored samples.
    """
    if executor not in EXECUTORS:
        raise TrainingError(f"executor must be 'local' or 'ray', got {executor!r}")
    streaming = bool(streaming) or executor == "ray"
    if streaming and select:
        raise TrainingError("--select fits its grid in memory; run it without --streaming / --executor ray, "
                            "then train the chosen hyperparameters with streaming")
    if n_fits is not None and int(n_fits) < 1:
        raise TrainingError(f"--fits must be >= 1, got {n_fits}")
    if streaming and n_fits is not None and int(n_fits) > 1:
        raise TrainingError("--fits pools fits made in memory; run it without --streaming / --executor ray")
    if mirror not in MIRROR_MODES:
        raise TrainingError(f"--mirror must be one of {', '.join(MIRROR_MODES)}, got {mirror!r}")
    if streaming and mirror == "on":
        raise TrainingError("--mirror on adds mirrored rows in memory; run it without --streaming / --executor ray")
    if roughness == "auto":
        roughness = None if streaming else "auto"
    elif streaming and roughness is not None:
        raise TrainingError("--roughness augments the rows in memory; run it without --streaming / --executor ray")
    root, name = resolve_dataset(preset, data_root)
    out = Path(out) if out is not None else Path("models") / f"{name}.npz"
    claim_files(report_paths(out), "train", recognise=is_training_output)  # before any work
    check_split_hashes(root, "train")
    if streaming:
        plan = DatasetShards.open(root, "train", executor=executor, workers=workers)
        split, metadata, rig = None, plan.metadata, plan.rig
        n, n_views, n_points = sum(plan.shard_rows()), plan.n_rig_views, plan.n_points
    else:
        split = load_split(root, "train", columns=["joints", "contours"])
        pa.default_memory_pool().release_unused()  # the Parquet reader's buffers (~200 MB on the paper preset)
        metadata, rig = split.metadata, split.rig
        n, n_views, n_points = len(split), split.contours.shape[1], split.contours.shape[2]
    if n < 4:
        raise TrainingError(f"{root}: the train split has {n} samples; at least 4 are needed")
    preset_note = None
    if not select:  # the dataset's own [train] settings, where the command line gives none
        preset = dataset_training(metadata, root)
        n_components = preset.get("components") if n_components is None else n_components
        n_latent = preset.get("latent") if n_latent is None else n_latent
        structure_weight = preset.get("structure_weight") if structure_weight is None else structure_weight
        if n_fits is None and preset.get("fits", 1) > 1 and streaming:
            preset_note = f"the dataset's [train] fits = {preset['fits']} not used: pooled fits are made in memory"
        elif n_fits is None:
            n_fits = preset.get("fits")
        if preset:
            used = ", ".join(f"{k} {preset[k]}" for k in TRAIN_FIELDS if k in preset)
            preset_note = preset_note or f"the dataset's [train] settings ({used}) where the command line gives none"
    n_fits = 1 if n_fits is None else int(n_fits)
    groups = clip_groups(root, "train")
    fit_idx, held_idx = heldout_split(n, heldout, seed, groups)
    if roughness == "auto":
        roughness = Roughness() if len(fit_idx) <= AUTO_ROUGHNESS_MAX_SAMPLES else None
    mirrors, mirror_note = choose_mirrors(rig, mirror, len(fit_idx), streaming)
    n_rows = len(fit_idx) * (1 + len(mirrors))  # the samples EM sees, before roughness copies
    contours, joints = (None, None) if split is None else (split.contours, split.joints)
    del split
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
            groups=None if groups is None else groups[fit_idx],
            max_iter=min(max_iter, 100), tol=tol, rig=rig, roughness=roughness, mirrors=mirrors,
            progress=(lambda i, k, row: print(f"  fit {i}/{k}: q={row['n_latent']} M={row['n_components']} "
                                              f"w={row['structure_weight']:g} -> {row['val_error_cm']:.2f} cm, "
                                              f"1 view {row['val_error_1view_cm']:.2f} cm, held-out log-lik "
                                              f"{row['val_loglik']:.1f}, {'real EM' if row['real_em'] else 'EM frozen'}",
                                              flush=True)) if progress else None,
        )
        print(selection.to_markdown())
        hp = {k: selection.best[k] for k in hp}
    notes = [note for note in (mirror_note, preset_note) if note]
    if not select:
        m_fit, q_fit = supported_size(n_rows, int(hp["n_components"]), int(hp["n_latent"]),
                                      fixed_m=n_components is not None, fixed_q=n_latent is not None)
        if (m_fit, q_fit) != (hp["n_components"], hp["n_latent"]):  # a small dataset cannot support the defaults
            counted = f"{n_rows} fitted samples" + (f" (with their {n_rows - len(fit_idx)} mirrored people)" if mirrors else "")
            notes.append(f"M, q lowered from the defaults {hp['n_components']}, {hp['n_latent']} to {m_fit}, {q_fit} "
                         f"for {counted}: EM needs >= {MIN_ROWS_PER_LATENT} samples per component "
                         f"per latent dimension to move from its k-means start")
            hp["n_components"], hp["n_latent"] = m_fit, q_fit
    max_q = min(len(fit_idx) - 1, n_points * 2 * (len(views) if views else n_views))
    if hp["n_latent"] >= max_q:
        raise TrainingError(f"n_latent = {hp['n_latent']} is too large for {len(fit_idx)} training samples (< {max_q})")
    for note in notes:
        print(f"note: {note}", flush=True)
    if not streaming:  # keep only the two parts, not the whole split, while EM runs
        c_held, j_held = contours[held_idx], joints[held_idx]
        c_fit, j_fit = contours[fit_idx], joints[fit_idx]
        del contours, joints

    with EMProgress(progress, max_iter, n_init) as em:
        model = ShapeStructureModel(
            hp["n_components"], hp["n_latent"], structure_weight=hp["structure_weight"], views=views,
            noise_variance=hp["noise_variance"], tol=tol, max_iter=max_iter, n_init=n_init, n_fits=int(n_fits),
            random_state=seed, callback=em,
        )
        t0 = time.perf_counter()
        if streaming:
            model.fit_stream(root, "train", rows=fit_idx, executor=executor, workers=workers)
        else:
            if roughness is not None or mirrors:
                c_fit, j_fit = training_rows(c_fit, j_fit, fit_idx, rig=rig, mirrors=mirrors, roughness=roughness,
                                             seed=seed)
            model.fit(c_fit, j_fit, rig=rig)
            del c_fit, j_fit
        wall = time.perf_counter() - t0
    release_freed_memory()  # EM's freed blocks, before the held-out inference allocates its own
    model.callback = None
    model.dataset_info_ = _dataset_info(root, name, metadata, n, len(fit_idx), len(held_idx))
    mode = {"streaming": streaming, "executor": executor if streaming else "in-memory",
            "n_shards": len(plan.paths) if streaming else None}
    model.training_config_ = {"command": "silpose train", "heldout_fraction": heldout, "seed": seed,
                              "heldout_by": "sample" if groups is None else "clip",
                              "select": bool(select), "selection_best": None if selection is None else selection.best,
                              "mode": mode, "roughness": None if roughness is None else roughness.to_dict(),
                              "mirrors": [m.to_dict() for m in mirrors]}
    held_1view = float("nan")
    if streaming:
        held_ll, held_err, held_contours = _heldout_streaming(model, plan, held_idx)
    else:
        held_contours = c_held
        held_ll = model.score_samples(c_held, j_held)
        held_err = pose_error_cm(model.infer(c_held).joints, j_held)
        held_1view = view_errors(model, np.asarray(c_held, np.float64), j_held)["one"]
    model.calibrate_plausibility(held_contours, seed=seed)  # stored in the model file (silpose.model.plausibility)
    if not streaming:  # the posterior mean's weights, calibrated on the clean held-out rows (silpose.model.mixing)
        model.mixing_ = calibrate_mixing(model, c_held, j_held)

    save_model(out, model)
    mix = model.mixture_
    q = int(model.n_latent)
    rows_per_comp = mix.weights_ * mix.n_fit_samples_ * int(model.n_fits)  # pooled fits: each fit's weights / n_fits
    report = {
        "model": str(out),
        "dataset": model.dataset_info_,
        "n_fit": int(len(fit_idx)),
        "n_heldout": int(len(held_idx)),
        "heldout_by": "sample" if groups is None else "clip",
        "mode": mode,
        "hyperparameters": model.hyperparameters(),
        "em": {
            "n_iter": int(mix.n_iter_),
            "converged": bool(mix.converged_),
            "real_em": is_real_em(mix, tol),
            "initial_loglik": float(mix.initial_bound_),
            "em_gain": float(mix.lower_bounds_[-1] - mix.initial_bound_),
            "mean_loglik": float(mix.lower_bound_),
            "train_loglik": float(unit_weight_loglik(model, mix.lower_bound_)),
            "loglik_curve": [float(v) for v in mix.lower_bounds_],
            "all_segments": em.curves,
            "fit_time_s": float(wall),
            "peak_rss_gib": peak_rss_bytes() / 2**30,
            "n_fit_rows": int(mix.n_fit_samples_),
            "pooled_runs": list(getattr(mix, "runs_", None) or []),
            "rows_per_component": {"min": float(rows_per_comp.min()), "median": float(np.median(rows_per_comp)),
                                   "max": float(rows_per_comp.max())},
            "rows_per_component_per_latent_min": float(rows_per_comp.min() / q),
            "noise_dof_factor": {"min": float(mix.noise_dof_factor_.min()), "median": float(np.median(mix.noise_dof_factor_)),
                                 "max": float(mix.noise_dof_factor_.max())},
            "n_underdetermined_components": int(mix.n_underdetermined_),
        },
        "heldout": {
            "mean_loglik": float(np.mean(unit_weight_loglik(model, held_ll))),
            "joint_error_cm": float(np.mean(held_err)),
            "joint_error_median_cm": float(np.median(held_err)),
            "joint_error_1view_cm": float(held_1view),
        },
        "mixing": None if getattr(model, "mixing_", None) is None else model.mixing_.to_dict(),
        "selection": None if selection is None else selection.to_dict(),
        "roughness": None if roughness is None else roughness.to_dict(),
        "mirrors": [m.to_dict() for m in mirrors],
        "notes": notes,
        "silpose_version": silpose_version(),
    }
    _, report_json, report_md = report_paths(out)
    write_text_atomic(report_json, json.dumps(report, indent=2))
    write_text_atomic(report_md, report_markdown(report, selection))
    return TrainingResult(out, report_md, report_json, report)


def choose_mirrors(rig, mode: str, n_fit: int, streaming: bool) -> tuple[tuple[RigMirror, ...], str]:
    """(the rig symmetries whose mirrored people ``silpose train --mirror mode`` adds, a note for the report
    when ``auto`` leaves some out, else "") -- see ``run_training``."""
    if mode == "off" or rig is None:
        return (), ""
    found = tuple(rig_mirrors(rig))
    if mode == "on":
        if not found:
            raise TrainingError(f"{rig.where}: --mirror on, but the rig has no mirror symmetry (no vertical plane maps "
                                f"its cameras onto each other; real calibrations never do): use --mirror auto or off")
        return found, ""
    if not found:
        return (), ""
    if streaming:
        return (), (f"the rig has {len(found)} mirror symmetr{'y' if len(found) == 1 else 'ies'}, but their mirror "
                    f"images are not added when streaming (--mirror on works in memory)")
    used = found[:max(0, AUTO_MIRROR_MAX_ROWS // max(n_fit, 1) - 1)]
    if len(used) < len(found):
        return used, (f"{len(used)} of the rig's {len(found)} mirror symmetries used: {n_fit} fitted samples with "
                      f"all their mirror images would pass {AUTO_MIRROR_MAX_ROWS:,} (--mirror on uses all)")
    return used, ""


def report_paths(model_path: Path) -> tuple[Path, Path, Path]:
    """What ``silpose train`` writes for the model file ``model_path``: (model, report .json, report .md)."""
    return model_path, model_path.with_suffix(".report.json"), model_path.with_suffix(".report.md")


def is_training_output(path: Path) -> bool:
    """True if ``path`` is a file ``silpose train`` wrote, which a new run may replace: a silpose model
    file, or a training report (.report.json with the report's keys, .report.md with its title)."""
    path = Path(path)
    try:
        if path.name.endswith(".report.json"):
            doc = json.loads(path.read_text())
            return isinstance(doc, dict) and {"model", "hyperparameters", "em", "heldout"} <= set(doc)
        if path.name.endswith(".report.md"):
            return path.read_text().startswith("# Training report: ")
    except (OSError, ValueError):
        return False
    return is_model_file(path)


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
        f"- silpose {r.get('silpose_version', 'unknown')}",
        f"- data: `{r['dataset']['root']}` train split, {r['n_fit']} samples fitted, {r['n_heldout']} held out "
        + ("(whole clips) " if r.get("heldout_by") == "clip" else "")
        + f"(manifest sha256 `{r['dataset']['manifest_sha256']}`)",
        f"- model: M = {hp['n_components']} components, q = {hp['n_latent']}, structure weight "
        f"{hp['structure_weight']:g}, views {hp['views'] if hp['views'] is not None else 'all'}, "
        f"inference noise s² = {hp['noise_variance']:g}",
        f"- EM: {em['n_iter']} iterations ({'converged' if em['converged'] else 'NOT converged'}, tol {hp['tol']:g}), "
        f"best of {hp['n_init']} runs, {em['fit_time_s']:.1f} s in total"
        + (f", peak memory of the process {em['peak_rss_gib']:.2f} GiB" if "peak_rss_gib" in em else "")
        + (f"; streamed over {r['mode']['n_shards']} shards ({r['mode']['executor']})" if r.get("mode", {}).get("streaming")
           else "; in memory"),
        f"- EM moved from its k-means start: {'yes' if em['real_em'] else 'NO'} (log-likelihood {em['initial_loglik']:.2f} "
        f"-> {curve[-1]:.2f} nats/sample, gain {em['em_gain']:.3g}); rows per component {em['rows_per_component']['min']:.0f}"
        f"-{em['rows_per_component']['max']:.0f} (at least {em['rows_per_component_per_latent_min']:.1f} per latent dimension)"
        + ("" if em["real_em"] else "; a fit whose EM never moves is its k-means partition with one PCA per cluster"),
        f"- noise variances corrected for degrees of freedom (x{em['noise_dof_factor']['min']:.2f}-"
        f"{em['noise_dof_factor']['max']:.2f}, {em['n_underdetermined_components']} components underdetermined)"
        if hp.get("noise_dof") else "- noise variances: maximum likelihood (no degrees-of-freedom correction)",
        f"- log-likelihood per sample (structure weight 1): training {em['train_loglik']:.1f}, held-out "
        f"{held['mean_loglik']:.1f} nats (gap {em['train_loglik'] - held['mean_loglik']:.1f})",
        f"- held-out joint error: all views observed mean {held['joint_error_cm']:.2f} cm, "
        f"median {held['joint_error_median_cm']:.2f} cm; one view observed (mean over views) "
        f"{held.get('joint_error_1view_cm', float('nan')):.2f} cm",
        *([f"- pooled: {hp.get('n_fits', 1)} EM fits from seeds {hp['random_state']}.."
            f"{hp['random_state'] + hp.get('n_fits', 1) - 1 if hp['random_state'] is not None else ''}, "
            f"iterations {[run['n_iter'] for run in em['pooled_runs']]}, gains "
            f"{[round(run['final_bound'] - run['initial_bound'], 2) for run in em['pooled_runs']]} nats/sample; "
            f"{hp['n_components'] * hp.get('n_fits', 1)} components in all; the curve below is the first fit's"]
          if em.get("pooled_runs") else []),
        *([f"- training augmentation: ragged outlines {r['roughness']}"] if r.get("roughness") else []),
        *([f"- training augmentation: the mirrored person of every fitted sample for each of the rig's "
           f"{len(r['mirrors'])} mirror symmetr{'y' if len(r['mirrors']) == 1 else 'ies'} (views "
           + "; ".join(", ".join(f"{a}<-{b}" for a, b in enumerate(m["view_map"])) for m in r["mirrors"]) + ")"]
          if r.get("mirrors") else []),
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
        how = selection.extra.get("choice", {})
        lines += ["", f"## Model selection ({selection.n_train} fit / {selection.n_val} validation samples)", "",
                  "Score: mean of the validation joint error given every view and given each view alone (ragged "
                  "validation outlines); log-likelihoods per sample for structure weight 1. Chosen among "
                  f"{how.get('pool', 'the fits')}: not dominated in (score, held-out log-likelihood), score within "
                  f"{100 * how.get('error_tolerance', 0):.0f} % of the best, then the fewest parameters.", "",
                  selection.to_markdown()]
    return "\n".join(lines) + "\n"

# ---------------------------------------------------------------- provenance: where a model's training data came from
# manifest_sha256 digests a dataset folder's manifest.json; the trainer (and fit_dataset) store it, with the folder
# and the generator config, in the model's dataset_info_, which silpose.model.persistence writes into the model file;
# check_split_hashes makes sure the shards a model is trained on are the ones the manifest hashed (as silpose
# validate does).


def file_sha256(path: str | Path) -> str:
    """Hex sha256 of a file's bytes (read in 1 MiB blocks)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def manifest_sha256(root: str | Path) -> str | None:
    """sha256 of ``<root>/manifest.json``, or None when the dataset folder has no manifest."""
    manifest = Path(root) / "manifest.json"
    return file_sha256(manifest) if manifest.is_file() else None


def check_split_hashes(root: str | Path, split: str) -> int:
    """Check ``split``'s shards in ``root`` against the sha256 values of ``root/manifest.json``.

    A dataset without a manifest, or with one that lists no shards, is not checked (returns 0).
    Otherwise every shard of the split on disk must be listed with its sha256 and match it, and every
    listed shard of the split must exist; a shard edited after generation (even only its footer,
    which the page checksums do not cover) raises :class:`~silpose.shared.dataset.DatasetError`
    naming the file. Returns the number of shards checked.
    """
    root = Path(root)
    path = root / "manifest.json"
    if not path.is_file():
        return 0
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise DatasetError(f"{path}: not valid JSON ({exc})") from None
    listed = manifest.get("shards") if isinstance(manifest, dict) else None
    if not isinstance(listed, list) or not listed:
        return 0
    hashes = {s.get("file"): s.get("sha256") for s in listed if isinstance(s, dict) and s.get("split") == split}
    shards = list_shards(root, split)
    for shard in shards:
        if shard.name not in hashes:
            raise DatasetError(f"{shard}: not listed in {path} (a shard of another run?); regenerate the dataset")
        if file_sha256(shard) != hashes[shard.name]:
            raise DatasetError(f"{shard}: sha256 differs from {path}: the shard was modified after generation; "
                               "regenerate it (silpose gen) or check it with silpose validate")
    missing = sorted(set(hashes) - {p.name for p in shards})
    if missing:
        raise DatasetError(f"{root / missing[0]}: listed in {path} but missing")
    return len(shards)


def fit_dataset(model, split):
    """Fit ``model`` (a ShapeStructureModel) on a ``silpose.shared.dataset.DatasetSplit`` (its contours, joints
    and rig) and record in ``dataset_info_`` (which the model file stores) the dataset folder, the sha256 of its
    ``manifest.json`` (when present) and the generator config. Returns the model."""
    model.fit(split.contours, split.joints, rig=split.rig)
    info: dict = {"n_samples": int(len(split.joints))}
    files = list(getattr(split, "files", []) or [])
    if files:
        root = files[0].parent
        info["root"] = str(root)
        info["manifest_sha256"] = manifest_sha256(root)
        info["config_name"] = (split.metadata.get("config") or {}).get("name")
        info["generator_config"] = split.metadata.get("config")
    model.dataset_info_ = info
    return model
