"""``silpose train`` and ``silpose infer``.

Only light modules are imported at module level (typer, pathlib, typing); numpy, sklearn,
pyarrow, OpenCV and rich are imported inside the commands, so ``silpose --help`` stays fast.
The work itself lives in ``silpose.model.training`` and ``silpose.model.inference_io``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated


from silpose.shared.cli import fail as _fail


def train(
    preset: Annotated[str, typer.Argument(help="Preset name (fits on data/<preset>/) or a dataset folder.")] = "default",
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Model file (default: models/<name>.npz).")] = None,
    select: Annotated[bool, typer.Option("--select", help="Choose q, M, structure weight and noise on a validation split first.")] = False,
    n_components: Annotated[Optional[int], typer.Option("--components", "-M", min=1, help="Mixture components M.")] = None,
    n_latent: Annotated[Optional[int], typer.Option("--latent", "-q", min=1, help="Latent dimension q per component.")] = None,
    structure_weight: Annotated[Optional[float], typer.Option(help="Weight of the joint block in the shape vector.")] = None,
    noise_variance: Annotated[Optional[float], typer.Option(help="Observation noise s² at inference (normalised units²).")] = None,
    views: Annotated[Optional[str], typer.Option(help="Views to model, comma-separated rig indices (default: all).")] = None,
    max_iter: Annotated[int, typer.Option(min=1, help="EM iterations per run at most.")] = 200,
    n_init: Annotated[int, typer.Option(min=1, help="EM runs from different k-means starts; the best is kept.")] = 3,
    tol: Annotated[float, typer.Option(help="EM stops when the mean log-likelihood gains less than this.")] = 1e-4,
    seed: Annotated[int, typer.Option(help="Seed of the k-means starts and the held-out/validation splits.")] = 0,
    heldout: Annotated[float, typer.Option(help="Fraction of train held out for the held-out log-likelihood.")] = 0.1,
    data_root: Annotated[Path, typer.Option(help="Folder holding the presets' datasets.")] = Path("data"),
    progress: Annotated[bool, typer.Option(help="Show EM progress.")] = True,
    streaming: Annotated[bool, typer.Option("--streaming", help="Out-of-core fit: EM reads the train shards one at a time "
                                            "(memory bounded by one shard, not the dataset).")] = False,
    executor: Annotated[str, typer.Option(help="Where the streaming EM runs its per-shard tasks: 'local' (this process) "
                                          "or 'ray' (one Ray task per shard; implies --streaming; uses the running Ray "
                                          "instance or RAY_ADDRESS, else starts a local one).")] = "local",
    workers: Annotated[Optional[int], typer.Option(min=1, help="CPUs of the local Ray instance if one is started (default: all cores).")] = None,
) -> None:
    """Fit the shape+structure model (mixture of PPCA over contours + joints) on a dataset's train split.

    Writes the model file and a training report (<model>.report.md and .json: EM iterations,
    log-likelihood curve, time, held-out log-likelihood and joint error on a held-out part of train).
    The model is fitted on the rest of train.

    By default the train split is loaded into memory. --streaming (or --executor ray) fits the
    same model by streaming EM over the Parquet shards (one shard's features in memory at a time;
    on Ray, one task per shard); the k-means + PPCA start is then fitted on at most 5,000 rows
    drawn across the shards (all rows if there are fewer, which gives the in-memory start).
    """
    from silpose.shared.dataset import DatasetError

    from .persistence import ModelFileError
    from .streaming import StreamingError
    from .training import TrainingError, run_training

    try:
        view_tuple = None if views is None else tuple(int(v) for v in views.split(",") if v.strip())
    except ValueError:
        _fail("train", f"--views must be comma-separated integers, got {views!r}")
    try:
        result = run_training(
            preset, out=out, select=select, n_components=n_components, n_latent=n_latent,
            structure_weight=structure_weight, noise_variance=noise_variance, views=view_tuple,
            max_iter=max_iter, n_init=n_init, tol=tol, seed=seed, heldout=heldout, data_root=data_root,
            progress=progress, streaming=streaming, executor=executor, workers=workers,
        )
    except (TrainingError, DatasetError, ModelFileError, StreamingError, ValueError) as exc:
        _fail("train", str(exc))
    except KeyboardInterrupt:
        _fail("train", "interrupted; nothing was written", 130)
    print(result.summary())


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
    Joints are written root-relative in metres (world orientation), as Parquet or JSON.
    """
    from silpose.shared.dataset import DatasetError

    from .inference_io import InferenceInputError, run_inference
    from .persistence import ModelFileError

    if (input is None) == (frames is None):
        _fail("infer", "give either INPUT (silhouettes or a dataset) or --frames DIR (camera frames), not both"
              if input is not None else "give INPUT (silhouettes or a dataset) or --frames DIR (camera frames)")
    if save_overlays and frames is None:
        _fail("infer", "--save-overlays needs --frames")
    try:
        if frames is not None:
            summary = _infer_frames(model, frames, out, save_contours, save_overlays, overlay_dir, min_area,
                                    noise_variance, progress)
        else:
            summary = run_inference(model, input, out=out, split=split, save_contours=save_contours,
                                    noise_variance=noise_variance, threshold=threshold)
    except (InferenceInputError, DatasetError, ModelFileError, ValueError) as exc:
        _fail("infer", str(exc))
    except KeyboardInterrupt:
        _fail("infer", "interrupted", 130)
    print(summary)


def _infer_frames(model, frames, out, save_contours, save_overlays, overlay_dir, min_area, noise_variance, progress):
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from .frames_io import run_frames_inference

    with Progress(TextColumn("[bold]segment + infer"), BarColumn(), TextColumn("{task.completed}/{task.total} frames"),
                  TimeElapsedColumn(), TimeRemainingColumn(), console=Console(stderr=True), disable=not progress,
                  transient=True) as bar:
        task = bar.add_task("frames", total=None)
        return run_frames_inference(model, frames, out=out, save_contours=save_contours, save_overlays=save_overlays,
                                    overlay_dir=overlay_dir, min_area=min_area, noise_variance=noise_variance,
                                    progress=lambda done, total: bar.update(task, completed=done, total=total))
