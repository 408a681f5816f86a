"""Load data and model, run the experiments, write every artefact into ``reports/<preset>/``.

Artefacts (each written atomically, :mod:`silpose.shared.atomic`):
``results.parquet`` (one row per experiment condition and test example), ``headline.json``,
``summary.md``, ``e1_single_vs_multi.png``, ``e2_missing_views.png``, ``e3_noise.png``,
``e4_baselines.png``, ``e5_single_view.png``, ``e5_missing_view.png``; with E6 also
``e6_flip_resolved.png``, ``e6_robust_mask.png``, ``e6_garbage.png`` (:mod:`silpose.eval.e6_figures`).
"""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from silpose.model.augment import Roughness, training_rows
from silpose.model.persistence import load_model
from silpose.app.heldout import clip_groups, heldout_split
from silpose.shared.atomic import atomic_path, write_json_atomic, write_text_atomic
from silpose.shared.dataset import DatasetError, load_split
from silpose.shared.metrics import CANVAS_MARGIN_PX
from silpose.shared.rig_symmetry import RigMirror
from silpose.shared.version import silpose_version

from . import e5_figures, e6_figures, plots
from .errors import EvalInputError
from .experiments import EvalConfig, EvalData, Evaluation, Progress, views_label
from .frames_eval import frames_note, write_frames_report
from .coverage import coverage
from .in_sample import in_sample_error
from .sequences import e7_markdown, plot_sequences, sequence_experiment
from .groups import group_headline, sample_groups, write_group_report
from .e6_inference import e6_markdown
from .report import headline, markdown_summary, pct_per_px
from .tables import fmt

__all__ = ["load_data", "match_training_subset", "write_reports", "frames_section", "run_evaluation", "EvalInputError",
           "test_sets_table", "write_test_sets"]


def load_data(data_dir: str | Path, n_test: int | None, with_masks: bool, test_dir: str | Path | None = None) -> EvalData:
    """Read ``data_dir``'s train split and the test split of ``test_dir`` (default ``data_dir``; test
    masks only if ``with_masks``). Another dataset's test split must have the same cameras and
    contour points (e.g. a test set generated from motion-capture clips)."""
    data_dir = Path(data_dir)
    test_dir = data_dir if test_dir is None else Path(test_dir)
    for d in dict.fromkeys((data_dir, test_dir)):
        if not d.is_dir():
            raise EvalInputError(f"{d}: no such dataset folder (generate it first: silpose gen {d.name})")
    try:
        train = load_split(data_dir, "train")
        test = load_split(test_dir, "test", with_masks=with_masks)
    except DatasetError as exc:
        raise EvalInputError(f"cannot read the dataset in {data_dir} / {test_dir}: {exc} (regenerate it)") from exc
    if len(train) == 0 or len(test) == 0:
        raise EvalInputError(f"{data_dir}: the train or test split is empty")
    if test_dir != data_dir:
        if train.rig.to_dict() != test.rig.to_dict():
            raise EvalInputError(f"{test_dir}: its cameras differ from those of the training data {data_dir}")
        if train.n_points != test.n_points:
            raise EvalInputError(f"{test_dir}: {test.n_points} contour points, the training data {data_dir} has {train.n_points}")
    return EvalData.from_splits(train, test, n_test)


def match_training_subset(data: EvalData, model, groups: np.ndarray | None = None) -> str:
    """Restrict ``data``'s training arrays to the samples the 4-view model was fitted on.

    ``silpose train`` holds out a seeded part of the train split (``silpose.app.heldout.heldout_split``: whole
    clips of a motion-capture dataset, else a random part of the rows); the single-view models, the baselines,
    chance and the in-sample figure must see the same samples, so E1 and E4 compare like with like. Reproduced
    from the model's ``dataset_info_`` (n_samples, n_heldout), its ``random_state`` and ``groups`` (N,), the
    train split's clip groups (``silpose.app.heldout.clip_groups``; None for a walk-only dataset); if that is
    impossible every training sample is used. Sets ``data.train_fitted``. Returns a note.
    """
    info = getattr(model, "dataset_info_", None) or {}
    n = len(data.train_joints)
    n_held, n_fit = int(info.get("n_heldout", 0) or 0), int(info.get("n_fit", n) or n)
    if n_held <= 0:
        data.train_fitted = n
        return f"single-view models and baselines are trained on all {n} training samples, like the 4-view model"
    if int(info.get("n_samples", -1)) != n:
        return (f"the model's training record ({info.get('n_samples')} samples) does not match this train split ({n}); "
                f"single-view models and baselines use all {n} samples")
    config = getattr(model, "training_config_", None) or {}
    seed = int(config.get("seed", model.random_state or 0))
    by_clip = config.get("heldout_by", "clip" if groups is not None else "sample") == "clip"
    fit_idx, _ = heldout_split(n, float(config.get("heldout_fraction", n_held / n)), seed, groups if by_clip else None)
    if len(fit_idx) != n_fit:
        return f"could not reproduce the trainer's held-out split; single-view models and baselines use all {n} samples"
    data.train_contours = data.train_contours[fit_idx]
    data.train_joints = data.train_joints[fit_idx]
    data.train_fitted = len(fit_idx)
    if data.train_groups is not None:
        data.train_groups = data.train_groups[fit_idx]
    rough = config.get("roughness")
    mirrors = tuple(RigMirror.from_dict(m) for m in config.get("mirrors") or ())
    extra = ""
    if rough or mirrors:  # the trainer's mirrored people and ragged copies (silpose.model.augment), row for row
        data.train_contours, data.train_joints = training_rows(
            data.train_contours, data.train_joints, fit_idx, rig=data.rig, mirrors=mirrors,
            roughness=Roughness(**rough) if rough else None, seed=seed)
        if data.train_groups is not None:  # row r of the augmented rows copies sample r mod n_fit: the same walker
            data.train_groups = data.train_groups[np.arange(len(data.train_joints)) % n_fit]
        if mirrors:
            extra += f", plus their mirrored people ({len(mirrors)} rig symmetr{'y' if len(mirrors) == 1 else 'ies'})"
        if rough:
            extra += f", plus the trainer's {int(rough['copies'])} ragged cop{'y' if rough['copies'] == 1 else 'ies'} of each"
    return (f"single-view models, baselines and chance use the same {n_fit} training samples as the 4-view model "
            f"(the trainer's {n_held} held-out samples reproduced and excluded{extra})")


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_reports(ev: Evaluation, out_dir: str | Path, settings: dict, title: str,
                  groups: dict[int, str] | None = None) -> dict[str, Path]:
    """Write the per-example rows, the headline JSON, the box plots, the E5 figures and summary.md.

    groups: ``{sample_id: activity group}`` of a test set posed from the motion library
    (:func:`silpose.eval.groups.sample_groups`): ``headline.json`` then also holds ``by_group``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    df = ev.frame()
    written: dict[str, Path] = {}
    with atomic_path(out / "results.parquet") as tmp:
        pq.write_table(pa.Table.from_pandas(df, preserve_index=False), tmp, compression="zstd")
    written["results"] = out / "results.parquet"
    for name, fn in (("e1_single_vs_multi", plots.plot_e1), ("e2_missing_views", plots.plot_e2),
                     ("e3_noise", plots.plot_e3), ("e4_baselines", plots.plot_e4)):
        p = fn(df, out / f"{name}.png")
        if p is not None:
            written[name] = p
    if "E5" in ev.config.experiments and "E2" in ev.config.experiments:
        for stem, views, caption in e5_figures.default_examples(ev.data.n_views):
            sid = e5_figures.median_example(df, "E2", views_label(views))
            if sid is not None:
                written[stem] = e5_figures.example_figure(ev, sid, views, out / f"{stem}.png",
                                                       caption + " — example nearest the median pose error")
    if ev.extra.get("E6"):
        written.update(e6_figures.write_e6_figures(ev, out))
    if ev.extra.get("E7"):  # silpose.eval.sequences: its figures, its JSON and its section of summary.md
        written["sequences"] = write_json_atomic(out / "sequences.json", ev.extra["E7"])
        figure = plot_sequences(ev.extra["E7"], out / "e7_sequences.png")
        if figure is not None:
            written["e7_sequences"] = figure
    head = _jsonable({"silpose_version": silpose_version(), **headline(df),
                      **({"e6": ev.extra["E6"]} if ev.extra.get("E6") else {}),
                      "chamfer_pct_per_px": pct_per_px(settings), "settings": settings, "timings_s": ev.timings,
                      "baseline_timing": ev.extra.get("baseline_timing", {}),
                      "mlp_baseline": ev.extra.get("mlp_baseline", {}),
                      "baseline_rows": ev.extra.get("baseline_rows", {}),
                      **({"by_group": group_headline(df, groups)} if groups else {})})
    write_text_atomic(out / "headline.json", json.dumps(head, indent=2))
    written["headline"] = out / "headline.json"
    pngs = [p.name for k, p in written.items() if p.suffix == ".png"]
    md = markdown_summary(df, _jsonable(settings), title, figures=pngs, notes=ev.notes,
                          sections=e6_markdown(ev.extra.get("E6") or {}) + e7_markdown(ev.extra.get("E7") or {}),
                          baseline_timing=ev.extra.get("baseline_timing"))
    write_text_atomic(out / "summary.md", md)
    written["summary"] = out / "summary.md"
    return written


def frames_section(ev: Evaluation, model, data_dir, out_dir, frames_dir, progress) -> dict[str, Path]:
    """Run the camera-frames evaluation if a frames dataset is there; add a note to the summary either way."""
    if frames_dir is False:
        return {}
    fdir = Path(data_dir) / "frames" if frames_dir in (None, True) else Path(frames_dir)
    if not fdir.is_dir():
        if frames_dir not in (None, True):
            raise EvalInputError(f"frames dataset {fdir} not found")
        ev.notes.append(f"camera frames: skipped, no frames dataset at {fdir}")
        return {}
    t0 = time.perf_counter()
    step = None if progress is None else (lambda done, total: progress("frames: segment + infer", done, total))
    try:
        fev, written = write_frames_report(fdir, model, out_dir, progress=step)
    except ValueError as exc:  # FramesInputError / SegmentError / DatasetError name the file
        raise EvalInputError(f"frames dataset {fdir}: {exc}") from exc
    ev.timings["frames"] = time.perf_counter() - t0
    ev.notes.append(frames_note(fev))
    return written


def run_evaluation(data_dir: str | Path, model_path: str | Path, out_dir: str | Path, config: EvalConfig,
                   progress: Progress | None = None, title: str | None = None,
                   frames_dir: str | Path | None | bool = None,
                   test_dir: str | Path | None = None) -> tuple[Evaluation, dict[str, Path]]:
    """Everything ``silpose eval`` does, without the terminal UI.

    ``frames_dir``: the camera-frames evaluation (:mod:`silpose.eval.frames_eval`, ``frames.md``) runs on
    this frames dataset; None = ``<data_dir>/frames`` when it exists (skipped with a note otherwise);
    False = never. ``test_dir``: take the test split from this dataset instead of ``data_dir`` (the
    training split, for the baselines and chance, stays ``data_dir``'s).
    """
    model_path = Path(model_path)
    if not Path(data_dir).is_dir():
        raise EvalInputError(f"{data_dir}: no such dataset folder (generate it first: silpose gen {Path(data_dir).name})")
    if not model_path.is_file():
        raise EvalInputError(f"{model_path}: no such model file (train it first: silpose train {Path(data_dir).name})")
    t0 = time.perf_counter()
    needs_masks = "E3" in config.experiments and any(s.needs_masks for s in config.sweep)
    data = load_data(data_dir, config.n_test, with_masks=needs_masks, test_dir=test_dir)
    try:
        model = load_model(model_path)
    except Exception as exc:  # persistence raises clear ValueErrors; keep its message
        raise EvalInputError(str(exc) if str(exc).startswith(str(model_path)) else f"{model_path}: {exc}") from exc
    if getattr(model, "n_rig_views_", data.n_views) != data.n_views or len(model.layout_.views) != data.n_views:
        raise EvalInputError(f"model {model_path} models views {model.layout_.views} of a {model.n_rig_views_}-view rig, "
                             f"but the evaluation needs a model over all {data.n_views} views of {data_dir}")
    train_note = match_training_subset(data, model, clip_groups(data_dir, "train"))
    load_s = time.perf_counter() - t0
    ev = Evaluation(data=data, model=model, config=config, progress=progress)
    ev.notes.append(train_note)
    ev.run()
    ev.timings["load"] = load_s
    frames_written = frames_section(ev, model, data_dir, out_dir, frames_dir, progress)
    settings = {
        "data": str(data_dir),
        "test_data": str(test_dir if test_dir is not None else data_dir),
        "model": str(model_path),
        "model_hyperparameters": model.hyperparameters(),
        "n_train": int(len(data.train_joints)),
        "training_subset": train_note,
        "n_test": int(len(data.test_ids)),
        "n_views": data.n_views,
        "test_contour_length_px_mean": None if data.test_length is None else float(np.mean(data.test_length)),
        "test_area_px_mean": None if data.test_area is None else float(np.mean(data.test_area)),
        "config": config.to_dict(),
        "chamfer_canvas_margin_px": CANVAS_MARGIN_PX,
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}",
    }
    if "E7" in config.experiments:  # recordings: the test clips played as sequences (silpose.eval.sequences)
        if progress is not None:
            progress("E7: sequences", 0, 1)
        seq = sequence_experiment(ev, test_dir if test_dir is not None else data_dir)
        if seq is not None:
            ev.extra["E7"] = seq
        if progress is not None:
            progress("E7: sequences", 1, 1)
    t1 = time.perf_counter()
    groups = sample_groups(test_dir if test_dir is not None else data_dir)
    if groups:
        ev.notes.append("every pose table per activity group of the test clips: groups.md")
    written = write_reports(ev, out_dir, settings, title or f"silpose evaluation — {Path(data_dir).name}", groups)
    if groups:
        written["groups"] = write_group_report(ev.frame(), groups, out_dir, title or f"silpose evaluation — {Path(data_dir).name}")
    cover = coverage(data_dir, test_dir)
    model_figures = in_sample_error(ev)
    if model_figures is not None:
        cover["model"] = model_figures
    written["coverage"] = write_json_atomic(Path(out_dir) / "coverage.json", cover)
    written.update(frames_written)
    ev.timings["reports"] = time.perf_counter() - t1
    return ev, written


def test_sets_table(rows: list[tuple[str, dict, int]]) -> str:
    """Markdown table of several test sets' headline figures: ``rows`` = (name, headline, n_test)."""
    head = ["test set", "n", "pose 4 views mean (cm)", "median", "pose 1 view mean (cm)", "kNN 4 views", "MLP 4 views",
            "MLP 1 view", "chance"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, h, n in rows:
        by = h.get("pose_cm_by_n_views", {})
        n_views = max(by) if by else None
        four = by.get(n_views, {}) if n_views else {}
        one = by.get(1, {})
        by_method = h.get("pose_mean_cm_by_method_and_n_views", {})
        knn = (by_method.get(n_views, {}) or {}).get("knn")
        mlp, mlp1 = (by_method.get(n_views, {}) or {}).get("mlp"), (by_method.get(1, {}) or {}).get("mlp")
        chance = h.get("chance_cm", {}).get("mean")
        cells = [name, str(n), fmt(four.get("mean")), fmt(four.get("median")), fmt(one.get("mean")), fmt(knn), fmt(mlp),
                 fmt(mlp1), fmt(chance)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_test_sets(out_dir: str | Path, model_path: str | Path, rows: list[tuple[str, dict, int]]) -> Path:
    """Write ``test_sets.md``: one model's headline figures on several test sets, side by side."""
    out = Path(out_dir) / "test_sets.md"
    text = (f"# One model on several test sets\n\nModel `{model_path}`; each test set's full report is in its own "
            "folder. Pose error: mean Euclidean distance over the 19 joints, root-relative, cm, with the standard "
            "test noise; chance = a random training pose; kNN = the k-nearest-neighbour baseline on all views; MLP = "
            "the MLP regression baseline.\n\n"
            + test_sets_table(rows) + "\n")
    return write_text_atomic(out, text)
