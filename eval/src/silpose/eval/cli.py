"""``silpose eval``: the paper's experiments on a generated dataset and a trained model.

Only light imports at module level (typer, pathlib, typing): numpy, sklearn, matplotlib and the
model are imported inside the command so ``silpose --help`` stays fast.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from silpose.shared.cli import fail, lazy_progress, show_progress


def evaluate(
    preset_or_data_dir: str = typer.Argument("default", help="Preset name (reads data/<preset>/) or a dataset folder."),
    model: Optional[Path] = typer.Option(None, help="Model file (default: models/<name>.npz)."),
    out: Optional[Path] = typer.Option(None, help="Output folder (default: reports/<name>/)."),
    n_test: Optional[int] = typer.Option(None, min=1, help="Use the first N test examples, and at most N sequences in E7 (default: all)."),
    seed: int = typer.Option(0, help="Seed of the test noise and the chance draws."),
    experiments: str = typer.Option("E1,E2,E3,E4,E5,E6,E7", help="Comma-separated subset of E1..E7 (E6: flips, robust "
                                    "inference, missing views, self-intersections, plausibility; E7: test clips or "
                                    "walkers played as 1 s recordings, each frame's answer vs the choice along the "
                                    "frames)."),
    jitter_px: Optional[float] = typer.Option(None, help="Standard test noise: per-point jitter in px (default 1)."),
    patch_depth_px: Optional[float] = typer.Option(None, help="Standard test noise: patch peak depth in px (default 8)."),
    n_patches: Optional[int] = typer.Option(None, help="Standard test noise: patches per view (default 6)."),
    patch_length: Optional[int] = typer.Option(None, help="Standard test noise: points per patch (default 30)."),
    quick_sweep: bool = typer.Option(False, help="E3 with 4 settings (clean, jitter 2px, patches 8px, mask strong)."),
    baseline_rows: int = typer.Option(20_000, min=0, help="Training samples the ridge and MLP baselines see at most, "
                                      "drawn by a fixed seed (0 = all; the MLP trains on 3 copies of each)."),
    frames: Optional[Path] = typer.Option(None, help="Frames dataset for the camera-frames evaluation (default: <data>/frames if it exists)."),
    no_frames: bool = typer.Option(False, "--no-frames", help="Skip the camera-frames evaluation."),
    test_data: Optional[List[Path]] = typer.Option(None, "--test-data", help="Evaluate on this dataset's test split "
                                                   "instead (repeat for several, e.g. test sets generated from "
                                                   "motion-capture clips); each gets its own report folder under "
                                                   "--out, and test_sets.md puts them side by side."),
) -> None:
    """Run experiments E1-E5 of the paper (section 6), E6 (how honest the inference is) and E7 (recordings: test
    clips played as sequences) and write reports/<name>/: summary.md, results.parquet, headline.json, coverage.json,
    sequences.json, box plots and example figures. Needs `just gen <preset>` and `just train <preset>` first.

    When data/<name>/frames holds a frames dataset (camera frames + truth), also segments the frames and
    writes frames.md (mask IoU; pose and Chamfer errors from segmented vs true silhouettes), frames.parquet,
    frames_errors.png and frames_example.png."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from contextlib import nullcontext

    from silpose.shared.output_dir import OutputFolderError, check_folder, claimed_folder

    from .experiments import DEFAULT_SWEEP, EvalConfig
    from .noise import STANDARD_NOISE
    from .errors import EvalInputError
    from .report import headline
    from .run import run_evaluation, write_test_sets

    console = Console(stderr=True)
    given = Path(preset_or_data_dir)
    if given.is_dir() or "/" in preset_or_data_dir:  # a folder (even a missing one), not a preset name
        data_dir, name = given, given.resolve().name
    else:
        data_dir, name = Path("data") / preset_or_data_dir, preset_or_data_dir
    model = model or Path("models") / f"{name}.npz"
    out = out or Path("reports") / name
    try:
        check_folder(out, "eval", recognise=is_report_folder)  # refuse before any work; claimed below
    except OutputFolderError as exc:
        fail("eval", str(exc))
    exps = tuple(e.strip().upper() for e in experiments.split(",") if e.strip())
    bad = [e for e in exps if e not in ("E1", "E2", "E3", "E4", "E5", "E6", "E7")]
    if bad:
        raise typer.BadParameter(f"unknown experiment(s) {bad}; choose from E1,E2,E3,E4,E5,E6,E7", param_hint="--experiments")
    changes = {k: v for k, v in dict(jitter_px=jitter_px, patch_depth_px=patch_depth_px, n_patches=n_patches,
                                      patch_length=patch_length).items() if v is not None}
    try:
        noise = STANDARD_NOISE.with_(**changes) if changes else STANDARD_NOISE
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from None
    sweep = DEFAULT_SWEEP
    if quick_sweep:
        sweep = tuple(s for s in DEFAULT_SWEEP if s.label in ("clean", "jitter 2px", "patches 8px", "mask strong"))
    config = EvalConfig(n_test=n_test, seed=seed, noise=noise, sweep=sweep, experiments=exps,
                        baseline_rows=baseline_rows or None)

    progress = Progress(TextColumn("[bold]{task.description:<42}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                        TimeElapsedColumn(), console=console, transient=False)
    with lazy_progress(progress):
        tasks: dict[str, int] = {}

        def on_step(what: str, done: int, total: int) -> None:
            key = what.split(":")[0]
            if key not in tasks:
                show_progress(progress)
                tasks[key] = progress.add_task(key, total=total)
            progress.update(tasks[key], completed=done, total=total, description=what[:42])

        runs = [(None, out, f"silpose evaluation — {name}")] if not test_data else [
            (t, out / t.name, f"silpose evaluation — model {model.name} on {t.name}") for t in test_data]
        rows = []
        try:
            # claimed for the run: a refused evaluation (bad model, bad data) leaves no folder behind
            with (claimed_folder(out, "eval", recognise=is_report_folder) if data_dir.is_dir() and model.is_file()
                  else nullcontext()):  # else run_evaluation says what is missing, writing nothing
                for test_dir, run_out, title in runs:
                    ev, written = run_evaluation(data_dir, model, run_out, config, progress=on_step, title=title,
                                                 frames_dir=False if (no_frames or test_dir is not None) else frames,
                                                 test_dir=test_dir)
                    console.print(f"wrote {len(written)} artefacts to {run_out}/ in {sum(ev.timings.values()):.0f} s:")
                    for key, path in written.items():
                        console.print(f"  {path}")
                    rows.append((run_out.name if test_dir is not None else name, headline(ev.frame()),
                                 len(ev.data.test_ids)))
        except (EvalInputError, OutputFolderError) as exc:
            if progress.live.is_started:
                progress.stop()  # before the error line
            fail("eval", str(exc))
    if test_data:
        console.print(f"  {write_test_sets(out, model, rows)}")


def is_report_folder(folder: Path) -> bool:
    """True if ``folder`` holds an evaluation written by ``silpose eval`` before output folders carried
    the marker of :mod:`silpose.shared.output_dir` (its ``headline.json`` with the run's settings)."""
    try:
        head = json.loads((Path(folder) / "headline.json").read_text())
    except (OSError, ValueError):
        return False
    return isinstance(head, dict) and isinstance(head.get("settings"), dict) and (Path(folder) / "summary.md").is_file()
