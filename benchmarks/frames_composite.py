"""A Blender-free frames dataset: camera frames composited from a silhouette dataset's true masks.

Writes the "frames dataset" layout (the contract with the Blender frames generator)::

    <out>/rig.json                        the dataset's rig (Rig.to_dict())
    <out>/background/<camera>/00000.png   empty-room frames per camera
    <out>/frames/<camera>/00000.png       frame i = test sample i, composited over the room
    <out>/test-00000-of-00001.parquet     the first n rows of the source's test split, unchanged
    <out>/README.md                       a card saying how it was made

The images come from :mod:`silpose.segment.composite` (textured room, cloth-coloured person from the
TRUE mask, a floor shadow, camera noise and flicker). Used by the tests and the frames-to-joints
benchmark; real camera-like frames come from the Blender generator. Every file is written
atomically (:mod:`silpose.shared.atomic`).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from silpose.segment.composite import background_frames, composite_frame, room
from silpose.shared.atomic import atomic_path, write_bytes_atomic, write_text_atomic
from silpose.shared.dataset import list_shards, load_split


def _write_png(path: Path, img: np.ndarray) -> None:
    ok, buf = cv2.imencode(".png", img)
    if not ok:
        raise OSError(f"{path}: OpenCV could not encode this image as PNG")
    write_bytes_atomic(path, buf.tobytes())


def write_composite_frames(dataset_dir, out_dir, n: int | None = None, n_background: int = 20, seed: int = 0,
                           noise_std: float = 3.0, flicker: float = 0.02, shadow_factor: float = 0.6) -> Path:
    """Write a composited frames dataset from the first ``n`` test samples of ``dataset_dir``.

    Args:
        dataset_dir: a silhouette dataset (its test split must hold masks).
        out_dir: the frames folder to create (must not exist or be empty).
        n: test samples (None = all).
        n_background: empty-room frames per camera.
        seed, noise_std, flicker, shadow_factor: see :func:`silpose.segment.composite.composite_frame`.
    Returns:
        ``out_dir``.
    """
    out = Path(out_dir)
    if out.exists() and any(out.iterdir()):
        raise FileExistsError(f"{out}: exists and is not empty")
    data = load_split(dataset_dir, "test", columns=["joints"], with_masks=True)
    n = len(data) if n is None else min(int(n), len(data))
    out.mkdir(parents=True, exist_ok=True)
    rig = data.rig
    write_text_atomic(out / "rig.json", rig.to_json())
    for k, cam in enumerate(rig):
        size = (cam.width, cam.height)
        bdir, fdir = out / "background" / cam.name, out / "frames" / cam.name
        bdir.mkdir(parents=True)
        fdir.mkdir(parents=True)
        for b, img in enumerate(background_frames(k, size, n_background, seed, noise_std, flicker)):
            _write_png(bdir / f"{b:05d}.png", img)
        clean = room(k, size, seed)
        for i in range(n):
            img = composite_frame(data.masks[i, k], k, i, seed, noise_std, flicker, shadow_factor, clean=clean)
            _write_png(fdir / f"{i:05d}.png", img)
    tables = [pq.read_table(p) for p in list_shards(dataset_dir, "test")]
    table = pa.concat_tables(tables).slice(0, n)
    with atomic_path(out / "test-00000-of-00001.parquet") as tmp:
        pq.write_table(table, tmp, compression="zstd")
    write_text_atomic(
        out / "README.md",
        f"# Composited frames dataset\n\nCamera frames composited from the true masks of the first {n} test samples "
        f"of `{dataset_dir}` by `benchmarks.frames_composite` (textured room per camera, cloth-coloured person "
        f"from the true mask, floor shadow factor {shadow_factor}, camera noise {noise_std} graylevels, flicker "
        f"±{flicker:.0%}, seed {seed}); NOT rendered by Blender.\n\n"
        "Layout: `rig.json` (the rig), `background/<camera>/NNNNN.png` "
        f"({n_background} empty-room frames per camera), `frames/<camera>/NNNNN.png` (frame i = test sample i), "
        "`test-00000-of-00001.parquet` (the truth: joints, masks, contours; `silpose.shared.dataset.load_split`).\n"
    )
    return out
