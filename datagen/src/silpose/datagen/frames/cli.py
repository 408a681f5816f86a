"""``silpose gen-frames``: textured camera frames + empty-room frames + truth.

Only light modules are imported at module level; the generator inside the command, and bpy only
in spawned workers. ``python -m silpose.datagen.frames.cli ...`` runs the command on its own.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from silpose.shared.cli import fail


def _fail(message: str, code: int = 2) -> None:
    fail("gen-frames", message, code)


def gen_frames(
    preset: Annotated[str, typer.Argument(help="Preset name in configs/ (smoke, default, paper) or a TOML file; its [frames] section sets the sizes.")] = "default",
    samples: Annotated[Optional[int], typer.Option("--samples", "-n", help="Person frames: test samples 0..N-1 (overrides frames.samples).")] = None,
    background: Annotated[Optional[int], typer.Option("--background", "-b", help="Empty-room frames per camera (overrides frames.background).")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Frames dataset folder (default: data/<name>/frames).")] = None,
    workers: Annotated[Optional[int], typer.Option("--workers", "-j", min=1, help="Worker processes (default: all cores).")] = None,
    progress: Annotated[bool, typer.Option(help="Show a progress bar.")] = True,
) -> None:
    """Render textured camera frames (Blender Cycles) of the preset's test samples in a room with
    props and floor shadows, plus empty-room background frames per camera, with camera noise and
    illumination flicker; the truth (masks, contours, joints) equals `silpose gen`'s test split.

    Output layout: rig.json, background/<camera>/NNNNN.png, frames/<camera>/NNNNN.png,
    test-*.parquet (truth), README.md. Built in a hidden .partial folder and renamed when complete;
    a rerun resumes it.
    """
    from silpose.shared.camera import RigError
    from silpose.shared.dataset import DatasetError
    from silpose.shared.output_dir import OutputFolderError, check_folder

    from ..motion.bvh_check import BvhError
    from ..motion.clips import ClipError
    from ..config import ConfigError
    from ..executor import ExecutorError
    from ..motion.joint_maps import JointMapError
    from ..motion.library import LibraryError
    from ..manifest import LockError
    from ..shards import GenerationError
    from .config import load_frames_config
    from .generate import FramesError, generate_frames, read_identity

    try:
        config, fcfg = load_frames_config(preset, samples=samples, background=background)
        target = out if out is not None else Path("data") / config.name / "frames"
        check_folder(target, "gen-frames", recognise=lambda p: read_identity(p) is not None)
        summary = generate_frames(config, fcfg, target, workers=workers, progress=progress)
    except (ConfigError, FramesError, GenerationError, LockError, DatasetError, ExecutorError, RigError,
            OutputFolderError, BvhError, ClipError, JointMapError, LibraryError) as exc:
        _fail(str(exc))
    except KeyboardInterrupt:
        _fail("interrupted; rerun the same command to resume", 130)
    if summary["already_complete"]:
        print(f"{target}: already complete ({fcfg.samples} samples, {fcfg.background} background frames per camera)")
        return
    secs = summary["image_seconds"]
    per = f"{sum(secs) / len(secs):.2f} s per rendered image" if secs else "nothing rendered"
    print(f"{target}: {fcfg.samples} samples x {len(config.rig)} cameras, {fcfg.background} background frames per "
          f"camera ({summary['tasks_rendered']} tasks rendered, {summary['tasks_skipped']} already done; {per}; "
          f"{summary['seconds']:.1f} s); card {Path(target) / 'README.md'}")


def main() -> None:
    app = typer.Typer(add_completion=False, pretty_exceptions_enable=False)
    app.command(name="gen-frames")(gen_frames)
    app()


if __name__ == "__main__":
    main()
