"""``silpose infer``: joints (and every view's contour) from silhouettes, camera frames or recordings (``--videos``).

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
    input: Annotated[Optional[Path], typer.Argument(help="A dataset folder, or a folder of per-camera folders of silhouette images: PNG, BMP, TIFF or JPEG (omit with --frames or --videos).")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Joints file: .parquet, or .json (default joints.parquet); with --videos an output folder (default <DIR>.silpose/).")] = None,
    split: Annotated[str, typer.Option(help="Split to read when INPUT is a dataset folder.")] = "test",
    save_contours: Annotated[bool, typer.Option("--contours", help="Also write reconstructed contours to <out stem>.contours.npz (with --videos: a contours_px column in joints.parquet).")] = False,
    noise_variance: Annotated[Optional[float], typer.Option(min=0.0, help="Observation noise s² (default: the model's).")] = None,
    threshold: Annotated[int, typer.Option(min=0, max=254, help="PNG pixels brighter than this are foreground (images holding only 0 and 1 are read as 0/1 masks).")] = 127,
    frames: Annotated[Optional[Path], typer.Option("--frames", help="Camera frames folder: background/<camera>/ and frames/<camera>/ (PNG/JPG folders or .mp4/.avi videos); segmented by background subtraction.")] = None,
    save_overlays: Annotated[bool, typer.Option("--save-overlays", help="With --frames: one PNG per frame (frames, silhouettes with reconstructed contours, inferred stick figure; paper Fig. 9) in <out stem>.overlays/.")] = False,
    overlay_dir: Annotated[Optional[Path], typer.Option(help="Folder of the --save-overlays figures (default <out stem>.overlays/).")] = None,
    min_area: Annotated[int, typer.Option(min=1, help="With --frames: a silhouette whose largest blob has fewer pixels is a missing view.")] = 50,
    progress: Annotated[bool, typer.Option(help="Show a progress bar (--frames, --videos).")] = True,
    videos: Annotated[Optional[Path], typer.Option("--videos", help="A recording: one video (or frame folder) per camera named as in the rig (or mapped in DIR/cameras.toml), several people; writes joints in the room, overlay videos and a floor plan to the --out folder.")] = None,
    masks: Annotated[bool, typer.Option("--masks", help="With --videos: the videos are foreground masks (lossy codecs are fine).")] = False,
    background_frames: Annotated[Optional[int], typer.Option("--background-frames", min=2, help="With --videos (colour): learn each camera's background from its first N frames (the empty room).")] = None,
    background: Annotated[Optional[Path], typer.Option("--background", help="With --videos (colour): a folder of empty-room clips, one per camera, named like the videos; or 'median': the recording's own per-pixel median (nobody stands still).")] = None,
    offsets: Annotated[Optional[str], typer.Option("--offsets", help="With --videos: per-camera frame offsets, e.g. 'cam1=3,cam2=-1' (cam1's frame i+3 was shot with the others' frame i).")] = None,
    overlays: Annotated[bool, typer.Option("--overlays/--no-overlays", help="With --videos: write the per-camera overlay videos.")] = True,
    video_min_area: Annotated[int, typer.Option("--blob-min-area", min=1, help="With --videos: blobs with fewer pixels are ignored (speckle).")] = 150,
    robust: Annotated[Optional[bool], typer.Option(help="Robust inference: contour points far from the reconstruction (holes, blobs, shadows) are down-weighted the loops such blobs add to an outline cut (column views_trimmed), and points slid along an outline by a bite or blob put back (column views_reindexed). Default: on, except for --videos --masks (the lab's own masks: measured more accurate and faster without it).")] = None,
    temporal: Annotated[Optional[bool], typer.Option(help="Choose among each frame's 3 hypotheses along the frames in order (one person); default: on with --frames, off otherwise (--videos always chooses along each person's track).")] = None,
) -> None:
    """Infer 3D joints (and reconstruct every view's contour) from multi-view silhouettes, camera frames or recordings.

    INPUT is either a dataset folder (its --split is read) or a folder with one subfolder per
    camera, named as in the model's rig, holding silhouette images (PNG, BMP, TIFF, JPEG); frames are matched by file name,
    and a missing camera folder, a missing file or an empty mask is a missing view.

    With --videos DIR (instead of INPUT): a recording of several people, one video per camera (mask videos
    with --masks, or colour videos with --background DIR / --background-frames N). People are found on the
    floor, tracked into stable ids, and each person's joints inferred from the views where their silhouette
    is theirs alone, placed in the room and written in silpose's frame and in the calibration's; --out is
    a folder: joints.parquet, joints.csv, overlays/<camera>.mp4, floorplan.png, summary.json.

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
    from ..writers import claim_outputs, sibling

    given = [name for name, v in (("INPUT", input), ("--frames", frames), ("--videos", videos)) if v is not None]
    if len(given) != 1:
        fail("infer", "give one of INPUT (silhouettes or a dataset), --frames DIR (camera frames) or --videos DIR "
                      "(a recording)" + (f", not {' and '.join(given)}" if given else ""))
    if save_overlays and frames is None:
        fail("infer", "--save-overlays needs --frames")
    video_only = {"--masks": masks, "--background-frames": background_frames is not None,
                  "--background": background is not None, "--offsets": offsets is not None}
    if videos is None and any(video_only.values()):
        fail("infer", f"{next(k for k, v in video_only.items() if v)} needs --videos")
    try:
        if videos is not None:
            summary = infer_videos(model, videos, out, masks, background, background_frames, offsets, overlays,
                                   video_min_area, noise_variance, progress, save_contours,
                                   (not masks) if robust is None else robust)
        else:
            out = out or Path("joints.parquet")
            claim_outputs(out, contours=save_contours, segmentation=frames is not None,
                          overlay_dir=(overlay_dir or sibling(out, ".overlays")) if save_overlays else None)
            if frames is not None:
                summary = infer_frames(model, frames, out, save_contours, save_overlays, overlay_dir, min_area,
                                       noise_variance, progress, robust is not False, True if temporal is None else temporal)
            else:
                summary = run_inference(model, input, out=out, split=split, save_contours=save_contours,
                                        noise_variance=noise_variance, threshold=threshold, robust=robust is not False,
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


def infer_videos(model, videos, out, masks, background, background_frames, offsets, overlays, min_area, noise_variance,
                 progress, contours=False, robust=True) -> str:
    """``silpose infer --videos``: :func:`~silpose.app.recordings.pipeline.run_recording` with a progress bar
    (frames/s) and warnings on stderr."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from silpose.shared.cli import lazy_progress, show_progress
    from silpose.shared.output_dir import claimed_folder

    from ..recordings.pipeline import RecordingOptions, run_recording

    console = Console(stderr=True)
    out = out if out is not None else Path(f"{Path(videos).name}.silpose")
    options = RecordingOptions(masks=masks, background=background, background_frames=background_frames,
                               offsets=offsets, overlays=overlays, min_area=min_area, noise_variance=noise_variance,
                               contours=contours, robust=robust)
    with claimed_folder(out, "infer"), lazy_progress(Progress(  # a refused recording leaves nothing behind
            TextColumn("[bold]recording"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[rate]} frames/s"),
            TimeElapsedColumn(), console=console, disable=not progress, transient=True)) as bar:
        task = bar.add_task("frames", total=None, rate="-")

        def update(done: int, total: int) -> None:
            show_progress(bar)
            elapsed = bar.tasks[0].elapsed or 0.0
            bar.update(task, completed=done, total=total if total >= 0 else None,
                       rate=f"{done / elapsed:.0f}" if elapsed > 0 else "-")

        summary = run_recording(model, videos, out, options, progress=update,
                                warn=lambda w: console.print(f"silpose infer: warning: {w}"))
    return summary.text()
