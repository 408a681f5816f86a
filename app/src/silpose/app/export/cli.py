"""``silpose export JOINTS --to trc|c3d|bvh``: the joints ``silpose infer`` wrote, for OpenSim, Pose2Sim,
Blender or a game engine. Only light imports at module level."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from silpose.shared.cli import fail

from .formats import EXPORTERS, exporter_names


def export(
    joints: Annotated[Path, typer.Argument(help="A joints file of silpose infer: joints.parquet or joints.csv of a "
                                                "recording (--videos), or the .parquet of a dataset or image folder.")],
    to: Annotated[str, typer.Option("--to", help=f"Format: {exporter_names()} ("
                                    + "; ".join(f"{e.name}: {e.what}" for e in EXPORTERS) + ").")],
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="File to write (default: JOINTS with the "
                                                                    "format's suffix).")] = None,
    frame: Annotated[str, typer.Option(help="silpose (metres, z up, floor z = 0) or calibration (a recording's "
                                            "joints in the calibration's own frame and units).")] = "silpose",
    person: Annotated[Optional[int], typer.Option(help="The person to export from a recording of several.")] = None,
    fps: Annotated[Optional[float], typer.Option(help="Frame rate (default: the recording's; 30 for a dataset or "
                                                      "image folder).")] = None,
) -> None:
    """Export joints to TRC (OpenSim, Pose2Sim), C3D or BVH (Blender, game engines).

    Units, axes and frame rate are written into the file: docs/conventions.md, "Export". Frames without
    joints stay in the file as missing markers (TRC, C3D) or hold the last pose (BVH).
    """
    from silpose.shared.output_dir import OutputFolderError, claim_files

    from .formats import get_exporter
    from .motion import ExportInputError, read_motion

    try:
        exporter = get_exporter(to)
        motion = read_motion(joints, frame=frame, person=person, fps=fps)
        target = out if out is not None else joints.with_suffix(exporter.suffix)
        if target.resolve() == joints.resolve():
            fail("export", f"{target}: --out names the joints file being exported")
        claim_files([target], "export", recognise=lambda p: p.suffix.lower() == exporter.suffix and
                    _written_by_silpose(p))
        written = exporter.write(motion, target)
    except (ExportInputError, OutputFolderError) as exc:
        fail("export", str(exc))
    except OSError as exc:
        fail("export", f"{out}: cannot write ({exc.strerror or exc})", 1)
    n_missing = int((~(motion.joints == motion.joints).all(axis=(1, 2))).sum())
    print(f"wrote {written}: {len(motion.frames)} frames at {motion.fps:g} fps, 19 joints in {motion.units}, "
          f"{motion.frame} frame" + (f"; {n_missing} frames without joints" if n_missing else ""))


def _written_by_silpose(path: Path) -> bool:
    """A previous export (its header names silpose's joints, ``head_top`` and ``r_toe`` among them): replaceable;
    anything else is refused."""
    try:
        with open(path, "rb") as f:
            head = f.read(16384)
    except OSError:
        return False
    return b"head_top" in head and b"r_toe" in head
