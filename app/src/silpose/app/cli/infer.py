"""``silpose infer``: joints (and every view's contour) from silhouettes, or from cameras (``--videos``, ``--frames``).

Only light modules are imported at module level (typer, pathlib, typing); numpy, OpenCV, pyarrow
and rich come with the work, imported inside the command (:mod:`silpose.app.inference`,
:mod:`silpose.app.recordings`), so ``silpose --help`` stays fast.
"""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated, Optional

import typer

from silpose.shared.cli import fail

from ..errors import InputError


class Overlays(str, Enum):
    """The values of ``--overlays`` (silpose.app.recordings.overlay_png.OVERLAY_FORMATS)."""

    png = "png"
    mp4 = "mp4"
    none = "none"


def infer(
    model: Annotated[Path, typer.Argument(help="Model file written by silpose train (.npz).")],
    input: Annotated[Optional[Path], typer.Argument(help="A dataset folder, or a folder of per-camera folders of silhouette images: PNG, BMP, TIFF or JPEG (omit with --frames or --videos).")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Joints file, .parquet or .json (default joints.parquet); for several people an output folder (default <DIR>.silpose/).")] = None,
    split: Annotated[str, typer.Option(help="Split to read when INPUT is a dataset folder.")] = "test",
    save_contours: Annotated[bool, typer.Option("--contours", help="Also write reconstructed contours: <out stem>.contours.npz, or for several people a contours_px column in joints.parquet.")] = False,
    noise_variance: Annotated[Optional[float], typer.Option(min=0.0, help="Observation noise s² (default: the model's).")] = None,
    threshold: Annotated[int, typer.Option(min=0, max=254, help="INPUT's PNG pixels brighter than this are foreground (images holding only 0 and 1 are read as 0/1 masks).")] = 127,
    videos: Annotated[Optional[Path], typer.Option("--videos", help="Cameras: one video (or frame folder) per camera named as in the rig (or mapped in DIR/cameras.toml), or a frames folder (frames/<camera>/ and background/<camera>/).")] = None,
    frames: Annotated[Optional[Path], typer.Option("--frames", help="A frames folder of one person: --videos DIR --people 1.")] = None,
    people: Annotated[Optional[int], typer.Option("--people", help="1: one person alone in view: each view's largest blob (whoever or whatever it is), no floor tracking, placed in the room by the views; joints root-relative with the root, in one file. Default: several people, found on the floor (a cluttered room too), tracked and placed in the room.")] = None,
    masks: Annotated[bool, typer.Option("--masks", help="The videos are foreground masks (lossy codecs are fine).")] = False,
    background: Annotated[Optional[Path], typer.Option("--background", help="Colour videos: a folder of empty-room clips, one per camera, named like the videos (a frames folder's background/ by default; the 60 frames around each clip's middle are used, each clip registered to its video first, for a camera nudged since); or 'median': the recording's own per-pixel median (nobody stands still).")] = None,
    background_frames: Annotated[Optional[int], typer.Option("--background-frames", min=2, help="Colour videos: learn each camera's background from its first N frames (the empty room).")] = None,
    offsets: Annotated[Optional[str], typer.Option("--offsets", help="Per-camera offsets in frames or seconds, e.g. 'cam1=3,cam2=-0.12s' (cam1's frame i+3 was shot with the others' frame i; cam2 started 0.12 s after them).")] = None,
    overlays: Annotated[Optional[Overlays], typer.Option("--overlays", help="Overlays of every frame: one PNG per frame (the cameras tiled) or one mp4 per camera (default: mp4 for several people, none for one).")] = None,
    overlay_dir: Annotated[Optional[Path], typer.Option(help="Folder of the overlays (default <out stem>.overlays/, for several people <out>/overlays/).")] = None,
    min_area: Annotated[Optional[int], typer.Option("--min-area", min=1, help="Blobs with fewer pixels (of the camera) are ignored (default: 3 % of a person's expected silhouette area at the working resolution).")] = None,
    min_hits: Annotated[Optional[int], typer.Option("--min-hits", min=1, help="Several people: frames in a row someone must be found on the floor before they become a person with an id (default: 0.3 s of the recording's frame rate, 25 frames/s for image folders). 1 for a few moments far apart or a very short clip: a ghost between people may then get an id too, and ids across moments far apart mean nothing.")] = None,
    progress: Annotated[bool, typer.Option(help="Show a progress bar (cameras).")] = True,
    robust: Annotated[Optional[bool], typer.Option(help="Robust inference: contour points far from the reconstruction (holes, blobs, shadows) are down-weighted, the loops such blobs add to an outline cut (column views_trimmed), and points slid along an outline by a bite or blob put back (column views_reindexed). Default: on, except for --masks (the lab's own masks: measured more accurate and faster without it).")] = None,
    carve: Annotated[Optional[bool], typer.Option(help="Several people: cut each person's views down to their visual hull (the part of each blob the other cameras support) before the views are judged, so clutter touching a person in one camera (a prop, a lamp, someone standing still) is cut off (column view_cut). Default: on for colour videos, off for --masks.")] = None,
    temporal: Annotated[Optional[bool], typer.Option(help="Choose among each frame's 8 most probable hypotheses along the frames in order and answer with the chosen one (one person); default: on for cameras, off for INPUT (several people: always along each person's track).")] = None,
    silhouette_fit: Annotated[bool, typer.Option(help="Cameras: move each joint, as little as its posterior uncertainty allows, inside the person's outline in every view used (the model's answer can put a wrist or an ankle beside the limb the cameras saw).")] = True,
    max_people: Annotated[Optional[int], typer.Option("--max-people", min=1, help="Several people: at most N ids (the head count, if known). A new person beyond N takes the id of the lost person who looks most alike (stature, build, clothing colours), wherever they were lost. Default: no limit.")] = None,
) -> None:
    """Infer 3D joints (and reconstruct every view's contour) from multi-view silhouettes or cameras.

    INPUT is either a dataset folder (its --split is read) or a folder with one subfolder per
    camera, named as in the model's rig, holding silhouette images (PNG, BMP, TIFF, JPEG); frames are matched by file name,
    and a missing camera folder, a missing file or an empty mask is a missing view.

    --videos DIR (instead of INPUT): one video or frame folder per camera (mask videos with --masks, or
    colour videos with --background DIR / --background-frames N), or a frames folder: DIR/frames/<camera>/
    and DIR/background/<camera>/ (empty-scene frames; the same file names in every camera folder), or
    <camera>.mp4/.avi videos. Several people are found on the floor, tracked into stable ids, and each
    person's joints inferred from the views where their silhouette is theirs alone, placed in the room and
    written in silpose's frame and in the calibration's; --out is a folder: joints.parquet, joints.csv,
    overlays/, floorplan.png, summary.json. --people 1: one person, each view's largest blob (no floor
    tracking), placed in the room by the views alone; joints root-relative in the --out file with the root
    (root_x/_y/_z) and the joints in the calibration's frame (<joint>_cal_x ...), each view's status in
    <out stem>.segmentation.json.
    --frames DIR is --videos DIR --people 1 for a frames folder.

    A camera without a video is a missing view; an empty or tiny segmentation is a missing view for that frame.
    Joints of INPUT and of one person are written root-relative in metres (world orientation), as Parquet or
    JSON: the single answer among the frame's 3 most probable hypotheses, or with --temporal the hypothesis chosen
    along the frames among 8 (their probabilities and facing directions are columns too). Every frame gets a plausibility percentile and a status: "implausible" frames
    (not a person, several people, a broken silhouette) and frames without any usable view are reported
    with a warning on stderr.
    """
    from silpose.model.persistence import ModelFileError
    from silpose.shared.dataset import DatasetError

    from ..inference import run_inference
    from ..writers import claim_outputs, sibling

    given = [name for name, v in (("INPUT", input), ("--frames", frames), ("--videos", videos)) if v is not None]
    if len(given) != 1:
        fail("infer", "give one of INPUT (silhouettes or a dataset), --videos DIR or --frames DIR (cameras)"
                      + (f", not {' and '.join(given)}" if given else ""))
    camera_only = {"--masks": masks, "--background-frames": background_frames is not None,
                   "--background": background is not None, "--offsets": offsets is not None,
                   "--people": people is not None, "--overlays": overlays is not None,
                   "--overlay-dir": overlay_dir is not None, "--min-area": min_area is not None,
                   "--min-hits": min_hits is not None, "--max-people": max_people is not None,
                   "--no-silhouette-fit": not silhouette_fit}
    if input is not None and any(camera_only.values()):
        fail("infer", f"{next(k for k, v in camera_only.items() if v)} needs --videos or --frames")
    if people is not None and people != 1:
        fail("infer", f"--people: {people} is not 1; omit --people for several people (found on the floor)")
    one = frames is not None or people == 1
    if one and min_hits is not None:
        fail("infer", "--min-hits is for several people (floor tracking); --people 1 and --frames track nobody")
    if one and max_people is not None:
        fail("infer", "--max-people is for several people (omit --people 1 / --frames)")
    shown = (overlays.value if overlays is not None else "none" if one else "mp4")
    if overlay_dir is not None and shown == "none":
        fail("infer", "--overlay-dir needs --overlays png or mp4")
    try:
        if input is not None:
            out = out or Path("joints.parquet")
            claim_outputs(out, contours=save_contours)
            summary = run_inference(model, input, out=out, split=split, save_contours=save_contours,
                                    noise_variance=noise_variance, threshold=threshold, robust=robust is not False,
                                    temporal=bool(temporal))
        else:
            from ..recordings.pipeline import RecordingOptions

            options = RecordingOptions(masks=masks, background=background, background_frames=background_frames,
                                       offsets=offsets, overlays=shown, min_area=min_area,
                                       noise_variance=noise_variance, contours=save_contours, min_hits=min_hits,
                                       robust=(not masks) if robust is None else robust, max_people=max_people or 0,
                                       carve=carve, silhouette_fit=silhouette_fit)
            source = frames if frames is not None else videos
            if one:
                out = out or Path("joints.parquet")
                overlay_dir = (overlay_dir or sibling(out, ".overlays")) if shown != "none" else None
                claim_outputs(out, contours=save_contours, segmentation=True, overlay_dir=overlay_dir)
                summary = infer_one_person(model, source, out, options, frames is not None, overlay_dir, progress,
                                           save_contours, True if temporal is None else temporal)
            else:
                summary = infer_videos(model, source, out, options, overlay_dir, progress)
    except (InputError, DatasetError, ModelFileError, ValueError) as exc:
        fail("infer", str(exc))
    except KeyboardInterrupt:
        fail("infer", "interrupted", 130)
    for line in summary.splitlines():
        if line.startswith("warning:"):
            typer.echo(f"silpose infer: {line}", err=True)
        else:
            print(line)


def _bar(console, progress: bool, label: str):
    """A transient progress bar on stderr (frames done / total, frames/s; started at the first update, run it in
    ``silpose.shared.cli.lazy_progress``) and its update(done, total) callback."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from silpose.shared.cli import show_progress

    bar = Progress(TextColumn(f"[bold]{label}"), BarColumn(), MofNCompleteColumn(),
                   TextColumn("{task.fields[rate]} frames/s"), TimeElapsedColumn(), console=console,
                   disable=not progress, transient=True)

    def update(done: int, total: int) -> None:
        show_progress(bar)
        task = bar.tasks[0]
        elapsed = task.elapsed or 0.0
        bar.update(task.id, completed=done, total=total if total >= 0 else None,
                   rate=f"{done / elapsed:.0f}" if elapsed > 0 else "-")

    return bar, update


def infer_one_person(model, source, out, options, frames_layout: bool, overlay_dir, progress, save_contours,
                     temporal) -> str:
    """``silpose infer --people 1`` / ``--frames``: :func:`~silpose.app.recordings.one_person.run_one_person_inference`
    with a progress bar and warnings on stderr."""
    from rich.console import Console

    from silpose.shared.cli import lazy_progress

    from ..recordings.one_person import run_one_person_inference

    console = Console(stderr=True)
    bar, update = _bar(console, progress, "one person")
    with lazy_progress(bar):
        bar.add_task("frames", total=None, rate="-")
        return run_one_person_inference(model, source, out=out, opt=options, frames_layout=frames_layout,
                                        temporal=temporal, save_contours=save_contours, overlay_dir=overlay_dir,
                                        progress=update, warn=lambda w: console.print(f"silpose infer: warning: {w}"))


def infer_videos(model, videos, out, options, overlay_dir, progress) -> str:
    """``silpose infer --videos`` (several people): :func:`~silpose.app.recordings.pipeline.run_recording` with a
    progress bar (frames/s) and warnings on stderr."""
    import dataclasses

    from rich.console import Console

    from silpose.shared.cli import lazy_progress
    from silpose.shared.output_dir import claim_folder, claimed_folder

    from ..recordings.pipeline import run_recording

    console = Console(stderr=True)
    out = out if out is not None else Path(f"{Path(videos).name}.silpose")
    if overlay_dir is not None:
        claim_folder(overlay_dir, "infer")
        options = dataclasses.replace(options, overlay_dir=overlay_dir)
    bar, update = _bar(console, progress, "recording")
    with claimed_folder(out, "infer"), lazy_progress(bar):  # a refused recording leaves nothing behind
        bar.add_task("frames", total=None, rate="-")
        summary = run_recording(model, videos, out, options, progress=update,
                                warn=lambda w: console.print(f"silpose infer: warning: {w}"))
    return summary.text()
