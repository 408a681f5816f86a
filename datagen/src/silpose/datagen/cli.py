"""``silpose gen``, ``silpose validate`` and ``silpose preview``.

Only light modules are imported here; numpy, pyarrow, matplotlib and the generator are imported
inside the commands, and bpy only ever inside spawned worker processes.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Optional

import typer

from silpose.shared.cli import fail


def gen(
    preset: Annotated[str, typer.Argument(help="Preset name in configs/ (smoke, default, paper) or a TOML file.")] = "default",
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Dataset folder (default: data/<name>).")] = None,
    workers: Annotated[Optional[int], typer.Option("--workers", "-j", min=1, help="Worker processes (default: all cores).")] = None,
    executor: Annotated[str, typer.Option(help="local (spawn process pool) or ray.")] = "local",
    rig: Annotated[
        Optional[Path],
        typer.Option("--rig", help="Rig file (rig.json from `silpose rig import`); replaces the config's [rig]."),
    ] = None,
    renderer: Annotated[Optional[str], typer.Option(help="Override the config: raster or blender.")] = None,
    blender_engine: Annotated[Optional[str], typer.Option(help="Override the config: workbench or cycles.")] = None,
    seed: Annotated[Optional[int], typer.Option(min=0, help="Override the config's dataset seed.")] = None,
    progress: Annotated[bool, typer.Option(help="Show a progress bar.")] = True,
    preview: Annotated[bool, typer.Option(help="Write preview.png and, with both splits, characters.png (shown in the card).")] = True,
) -> None:
    """Generate a dataset of multi-view silhouettes and 3D joints (Parquet shards, card, manifest, preview).

    A rerun into the same folder resumes: complete shards are kept, the rest are rendered.
    """
    from silpose.shared.camera import RigError
    from silpose.shared.dataset import DatasetError
    from silpose.shared.output_dir import OutputFolderError, claim_folder

    from .motion.bvh_check import BvhError
    from .motion.clips import ClipError
    from .config import ConfigError, load_config
    from .executor import ExecutorError
    from .motion.joint_maps import JointMapError
    from .motion.library import LibraryError
    from .manifest import LockError, is_dataset_folder
    from .pipeline import generate
    from .shards import GenerationError

    overrides: dict = {"renderer": renderer, "blender_engine": blender_engine, "seed": seed}
    if rig is not None:
        overrides["rig"] = {"file": str(rig.expanduser().resolve())}
    try:
        config = load_config(preset, **overrides)
        target = out if out is not None else Path("data") / config.name
        claim_folder(target, "gen", recognise=is_dataset_folder)
        if config.placement is not None:
            print(f"note: some camera misses parts of the rig's workspace ({config.rig.workspace.describe()}); walkers "
                  f"are placed on the part every camera sees: {config.placement.describe()}", file=sys.stderr)
        manifest = generate(config, target, workers=workers, executor=executor, progress=progress,
                            preview=preview, card=True)
    except (ConfigError, GenerationError, LockError, DatasetError, ExecutorError, RigError, OutputFolderError,
            BvhError, ClipError, JointMapError, LibraryError) as exc:
        fail("gen", str(exc))
    except KeyboardInterrupt:
        fail("gen", "interrupted; rerun the same command to resume", 130)
    t = manifest["timing"]
    counts = ", ".join(f"{n} {s}" for s, n in manifest["counts"].items())
    rate = f"{t['samples_per_second']} samples/s" if t["samples_per_second"] else "nothing to render"
    print(
        f"{target}: {counts} samples in {len(manifest['shards'])} shards "
        f"({t['shards_rendered']} rendered, {t['shards_skipped']} already complete; {rate}); card {target / 'README.md'}"
    )


def validate(
    path: Annotated[Path, typer.Argument(help="Dataset folder (or a single shard .parquet file).")],
) -> None:
    """Check a dataset: schema, counts, NaNs, joints inside silhouettes, contours on the boundary, hashes."""
    from silpose.shared.dataset import DatasetError, read_shard

    from .validate import validate_dataset

    if path.is_file():
        try:
            shard = read_shard(path, with_masks=True)
        except DatasetError as exc:
            fail("validate", str(exc), 1)
        print(f"{path}: readable silpose shard, {len(shard)} samples, {shard.n_views} views")
        return
    if not path.is_dir():
        fail("validate", f"{path}: no such dataset folder or shard file")  # an input error: 2, as train says
    report = validate_dataset(path)
    print(report.format())
    if not report.ok:
        raise typer.Exit(1)


def preview(
    path: Annotated[Path, typer.Argument(help="Dataset folder.")],
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="PNG path (default: DIR/preview.png).")] = None,
    samples: Annotated[int, typer.Option(min=1, max=32, help="Samples (rows) in the sheet.")] = 4,
    split: Annotated[Optional[str], typer.Option(help="Split to show (default: train).")] = None,
) -> None:
    """Write a contact sheet PNG: a few samples x all views, mask, contour and projected joints."""
    from silpose.shared.dataset import DatasetError
    from silpose.shared.output_dir import OutputFolderError, claim_picture

    from .preview import write_preview

    if out is not None:  # the default DIR/preview.png lives in the dataset folder, silpose's own
        try:
            claim_picture(out, "preview")
        except OutputFolderError as exc:
            fail("preview", str(exc), 1)
    try:
        written = write_preview(path, out, n_samples=samples, split=split)
    except (DatasetError, StopIteration) as exc:
        fail("preview", str(exc) or f"{path}: no shards", 1)
    print(written)
