"""``silpose motions import`` and ``silpose motions list``: the motion library from the command line.

Only light modules are imported here; the library code (numpy, pyarrow) inside the commands, and
Blender only ever in the spawned import workers.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from silpose.shared.cli import fail

app = typer.Typer(help="The motion library: motion-capture clips silpose poses bodies with (`[motion] source = \"library\"`).",
                  no_args_is_help=True, add_completion=False)


def _subject_order(s: str) -> tuple[int, str]:
    """Numeric subjects in numeric order (2 before 13), then the others."""
    return (int(s), "") if s.isdigit() else (1 << 30, s)


#: Clip files ``silpose motions import`` finds in folders: BVH, the AMC motions of ASF/AMC, FBX and glTF.
CLIP_SUFFIXES = (".bvh", ".amc", ".fbx", ".glb", ".gltf", ".trc", ".c3d")


def subject_of(path: Path) -> str:
    """``--subject auto``: the file name up to its first ``_`` (the CMU database's ``86_01`` -> ``86``), leading
    zeros dropped from a number (``02_01`` -> ``2``, as the bundled library writes CMU subjects); the whole stem
    when it has no ``_``."""
    head = path.stem.split("_", 1)[0]
    return str(int(head)) if head.isdigit() else head


def _bvh_files(paths: list[Path]) -> tuple[list[Path], list[str]]:
    """Clip files of ``paths`` (folders searched recursively for :data:`CLIP_SUFFIXES`, files taken
    as given), and one line per path that does not exist or holds no clip."""
    files, missing = [], []
    for p in paths:
        if p.is_dir():
            found = sorted(q for q in p.rglob("*") if q.suffix.lower() in CLIP_SUFFIXES and q.is_file())
            if not found:
                missing.append(f"{p}: no clip file ({', '.join(CLIP_SUFFIXES)}) in this folder")
            files += found
        elif p.is_file():
            files.append(p)
        else:
            missing.append(f"{p}: no such file or folder")
    return files, missing


@app.command("import")
def import_(
    paths: Annotated[list[Path], typer.Argument(help="BVH, AMC, FBX, glTF (.glb/.gltf), TRC or C3D (joint keypoints: Pose2Sim, OpenSim, silpose export) files, or folders (searched recursively for them; an AMC file's skeleton is the .asf beside it).")],
    library: Annotated[Path, typer.Option("--library", "-l", help="Library folder to create or extend (only silpose's own files may be in it).")] = Path("motion-library"),
    group: Annotated[str, typer.Option(help="Activity group of every imported clip (e.g. walk, dance, sports).")] = "other",
    split: Annotated[str, typer.Option(help="train or test (hold out whole subjects for test).")] = "train",
    subject: Annotated[str, typer.Option(help="Performer of the clips (recorded; held-out test sets hold out subjects). "
                                              "'auto': each file's name up to its first '_' (CMU: 86_01.amc -> 86).")] = "",
    licence: Annotated[str, typer.Option(help="Licence / source of the clips, recorded with each clip and shown in dataset cards.")] = "",
    scale: Annotated[float, typer.Option(min=0.0, help="Metres per BVH unit (1.0 m, 0.01 cm, 0.056444 CMU conversions). ASF/AMC, FBX, glTF, TRC and C3D clips are read in metres: leave 1.")] = 1.0,
    joint_map: Annotated[str, typer.Option("--joint-map", help="auto, a built-in map (cmu, mixamo, hip-knee, bandai, cc-base, daz, mocapnet, cmu-asf, keypoints) or a TOML file.")] = "auto",
    first: Annotated[int, typer.Option(min=0, help="First frame kept (1 drops a calibration pose in frame 0).")] = 0,
    fps: Annotated[float, typer.Option(min=1.0, help="Frame rate the clips are thinned to.")] = 30.0,
    amc_fps: Annotated[float, typer.Option("--amc-fps", min=1.0, help="Frame rate of AMC files, which do not state it (the CMU database's: 120).")] = 120.0,
    workers: Annotated[Optional[int], typer.Option("--workers", "-j", min=1, help="Import processes (default: all cores).")] = None,
    progress: Annotated[bool, typer.Option("--progress/--no-progress", help="Show a progress bar over the files read.")] = True,
) -> None:
    """Import BVH, ASF/AMC, FBX, glTF, TRC or C3D clips into a motion library (BVH, FBX and glTF read by
    Blender's own importers, ASF/AMC and the joint keypoints of TRC and C3D files by silpose's; stored as bone
    directions and root motion). A clip that cannot be imported is reported in one line and skipped."""
    from .build import ClipSource, import_clips
    from .joint_maps import BUILTIN_MAPS
    from .library import LibraryError

    if split not in ("train", "test"):
        fail("motions import", f"--split must be train or test, got {split!r}")
    if joint_map != "auto" and joint_map not in BUILTIN_MAPS and not Path(joint_map).is_file():
        fail("motions import", f"--joint-map {joint_map!r}: neither a built-in map ({', '.join(BUILTIN_MAPS)}) nor a file")
    files, missing = _bvh_files(paths)
    for line in missing:
        typer.echo(f"skipped: {line}", err=True)
    sources = [ClipSource(path=f.resolve(), group=group, split=split, subject=subject_of(f) if subject == "auto" else subject,
                          licence=licence, scale=scale,
                          joint_map=str(Path(joint_map).resolve()) if Path(joint_map).is_file() else joint_map,
                          first=first, source=str(f), amc_fps=amc_fps) for f in files]
    if not sources:
        fail("motions import", "no clip file to import")
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from silpose.shared.cli import lazy_progress, show_progress

    bar = Progress(TextColumn("[bold]import"), BarColumn(), MofNCompleteColumn(), TextColumn("clips"), TimeElapsedColumn(),
                   TimeRemainingColumn(), console=Console(stderr=True), disable=not progress)
    with lazy_progress(bar):
        job = bar.add_task("import", total=None)

        def advance(done: int, total: int) -> None:
            if total:
                show_progress(bar)
                bar.update(job, completed=done, total=total)

        try:
            report, error = import_clips(sources, library, fps=fps, workers=workers, progress=advance), None
        except LibraryError as exc:  # reported once the bar is gone
            report, error = None, str(exc)
    if report is None:
        fail("motions import", error)
        return
    for line in report.skipped:
        typer.echo(f"skipped: {line}", err=True)
    typer.echo(f"{library}: {len(report.added)} clips imported, {len(report.skipped) + len(missing)} skipped, "
               f"{report.kept} kept from before")


def _library(folder: Optional[Path], command: str):
    """The library at ``folder`` (None: the bundled one); a one-line error naming it otherwise."""
    from .library import LibraryError, load_library

    try:
        return load_library(folder)
    except LibraryError as exc:
        fail(command, str(exc))


@app.command("show")
def show(
    clip: Annotated[str, typer.Argument(help="Clip id, as `silpose motions list` prints it (e.g. cmu_05_12).")],
    library: Annotated[Optional[Path], typer.Option("--library", "-l", help="Library folder (default: the one bundled with silpose).")] = None,
    frames: Annotated[int, typer.Option("--frames", "-n", min=1, max=40, help="Frames drawn, evenly spaced over the clip.")] = 8,
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="PNG to write (default: <clip>.png here).")] = None,
) -> None:
    """Draw a clip of a motion library as stick figures, front and side, feet on the floor: check what an
    import made of a file (joint map, left and right, up axis) before generating data with it."""
    from .clip_sheet import write_clip_sheet

    lib = _library(library, "motions show")
    target = out if out is not None else Path(clip.replace("/", "_") + ".png")
    if target.suffix.lower() != ".png":
        fail("motions show", f"{target}: --out must be a .png file")
    try:
        written = write_clip_sheet(lib, clip, target, frames)
    except KeyError as exc:
        fail("motions show", exc.args[0])
        return
    except OSError as exc:
        fail("motions show", f"{target}: cannot write ({exc.strerror or exc})", 1)
        return
    typer.echo(f"wrote {written}")


@app.command("list")
def list_(
    library: Annotated[Optional[Path], typer.Option("--library", "-l", help="Library folder (default: the one bundled with silpose).")] = None,
    clips: Annotated[bool, typer.Option("--clips/--groups", help="One line per clip (default) or per group.")] = True,
) -> None:
    """Print a motion library by activity group: clips, subjects, frames, splits and licences."""
    lib = _library(library, "motions list")
    m = lib.manifest
    groups = sorted({c["group"] for c in lib.clips}, key=lambda g: (g != "walk", g))
    typer.echo(f"{lib.folder}: {len(lib.clips)} clips, {len({c.get('subject') for c in lib.clips})} subjects, "
               f"{len(groups)} groups, {len(lib.frame)} frames at {m.get('fps')} fps")
    for g in groups:
        cs = [c for c in lib.clips if c["group"] == g]
        per = {s: sum(c["split"] == s for c in cs) for s in ("train", "test")}
        typer.echo(f"{g}: {len(cs)} clips ({per['train']} train, {per['test']} test), "
                   f"{sum(int(c['frames']) for c in cs)} frames, subjects {', '.join(sorted({str(c.get('subject', '')) for c in cs}, key=_subject_order))}")
        if clips:
            for c in cs:
                typer.echo(f"  {c['id']:<14} subject {str(c.get('subject', '-')):<4} {c['split']:<5} {int(c['frames']):>5} frames  "
                           f"{c.get('description', '')[:48]:<48}  {c['licence'] or '-'}")
    licences = sorted({c["licence"] or "-" for c in lib.clips})
    typer.echo("licences: " + "; ".join(licences))
    if m.get("acknowledgement"):
        typer.echo(f"acknowledgement: {m['acknowledgement']}")
