"""``silpose infer``: joints (and every view's contour) from silhouettes or camera frames.

Only light modules are imported at module level (typer, pathlib, typing); numpy, OpenCV, pyarrow
and rich come with the work, imported inside the command (:mod:`silpose.app.inference`,
:mod:`silpose.app.frames_pipeline`), so ``silpose --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from silpose.shared.cli import fail

from ..errors import InputError


def infer(
    model: Annotated[Path, typer.Argument(help="Model file written by silpose train (.npz).")],
    input: Annotated[Optional[Path], typer.Argument(help="A dataset folder, or a folder of per-camera silhouette PNG folders (omit with --frames).")] = None,
    out: Annotated[Path, typer.Option("--out", "-o", help="Joints file: .parquet, or .json.")] = Path("joints.parquet"),
    split: Annotated[str, typer.Option(help="Split to read when INPUT is a dataset folder.")] = "test",
    save_contours: Annotated[bool, typer.Option("--contours", help="Also write reconstructed contours to <out stem>.contours.npz.")] = False,
    noise_variance: Annotated[Optional[float], typer.Option(help="Observation noise s² (default: the model's).")] = None,
    threshold: Annotated[int, typer.Option(min=0, max=254, help="PNG pixels brighter than this are foreground.")] = 127,
    frames: Annotated[Optional[Path], typer.Option("--frames", help="Camera frames folder: background/<camera>/ and frames/<camera>/ (PNG/JPG folders or .mp4/.avi videos); segmented by background subtraction.")] = None,
    save_overlays: Annotated[bool, typer.Option("--save-overlays", help="With --frames: one PNG per frame (frames, silhouettes with reconstructed contours, inferred stick figure; paper Fig. 9) in <out stem>.overlays/.")] = False,
    overlay_dir: Annotated[Optional[Path], typer.Option(help="Folder of the --save-overlays figures (default <out stem>.overlays/).")] = None,
    min_area: Annotated[int, typer.Option(min=1, help="With --frames: a silhouette whose largest blob has fewer pixels is a missing view.")] = 50,
    progress: Annotated[bool, typer.Option(help="Show a progress bar (--frames).")] = True,
    robust: Annotated[bool, typer.Option(help="Robust inference: contour points far from the reconstruction (holes, blobs, shadows) are down-weighted.")] = True,
    temporal: Annotated[Optional[bool], typer.Option(help="Choose among each frame's 3 hypotheses along the frames in order (one person); default: on with --frames, off otherwise.")] = None,
) -> None:
    """Infer 3D joints (and reconstruct every view's contour) from multi-view silhouettes or camera frames.

    INPUT is either a dataset folder (its --split is read) or a folder with one subfolder per
    camera, named as in the model's rig, holding silhouette PNGs; frames are matched by file name,
    and a missing camera folder, a missing file or an empty mask is a missing view.

    With --frames DIR (instead of INPUT), DIR holds background/<camera>/ (empty-scene frames) and
    frames/<camera>/ (same file names in every camera folder), or <camera>.mp4/.avi videos; each
    camera's frames are segmented by background subtraction (the paper's), contours extracted and
    joints inferred. A camera without a folder is a missing view; an empty or tiny segmentation is
    a missing view for that frame, recorded in <out stem>.segmentation.json.
    Joints are written root-relative in metres (world orientation), as Parquet or JSON: the single
    answer among the frame's 3 most probable hypotheses (their probabilities and facing directions are
    columns too). Every frame gets a plausibility percentile and a status: "implausible" frames (not a
    person, several people, a broken silhouette) and frames without any usable view are reported
    with a warning on stderr.
    """
    from silpose.model.persistence import ModelFileError
    from silpose.shared.dataset import DatasetError

    from ..inference import run_inference

    if (input is None) == (frames is None):
        fail("infer", "give either INPUT (silhouettes or a dataset) or --frames DIR (camera frames), not both"
              if input is not None else "give INPUT (silhouettes or a dataset) or --frames DIR (camera frames)")
    if save_overlays and frames is None:
        fail("infer", "--save-overlays needs --frames")
    try:
        if frames is not None:
            summary = infer_frames(model, frames, out, save_contours, save_overlays, overlay_dir, min_area,
                                    noise_variance, progress, robust, True if temporal is None else temporal)
        else:
            summary = run_inference(model, input, out=out, split=split, save_contours=save_contours,
                                    noise_variance=noise_variance, threshold=threshold, robust=robust,
                                    temporal=bool(temporal))
    except (InputError, DatasetError, ModelFileError, ValueError) as exc:
        fail("infer", str(exc))
    except KeyboardInterrupt:
        fail("infer", "interrupted", 130)
    for line in summary.splitlines():
        if line.startswith("warning:"):
            typer.echo(f"silpose infer: {line}", err=True)
        else:
            print(line)


def infer_frames(model, frames, out, save_contours, save_overlays, overlay_dir, min_area, noise_variance, progress,
                 robust: bool = True, temporal: bool = True) -> str:
    """``silpose infer --frames``: :func:`~silpose.app.frames_pipeline.run_frames_inference` with a progress bar."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from ..frames_pipeline import run_frames_inference

    with Progress(TextColumn("[bold]segment + infer"), BarColumn(), TextColumn("{task.completed}/{task.total} frames"),
                  TimeElapsedColumn(), TimeRemainingColumn(), console=Console(stderr=True), disable=not progress,
                  transient=True) as bar:
        task = bar.add_task("frames", total=None)
        return run_frames_inference(model, frames, out=out, save_contours=save_contours, save_overlays=save_overlays,
                                    overlay_dir=overlay_dir, min_area=min_area, noise_variance=noise_variance,
                                    progress=lambda done, total: bar.update(task, completed=done, total=total),
                                    robust=robust, temporal=temporal)
