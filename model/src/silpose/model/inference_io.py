"""The work behind ``silpose infer``: read contours from a dataset split or per-camera PNG folders,
infer, and write joints (Parquet or JSON) and optionally the reconstructed contours (.npz).

PNG input layout::

    INPUT/<camera name>/<frame>.png      one folder per camera, named as in the model's rig

Frames are matched by file name across cameras. A missing camera folder, a frame file absent from
one camera's folder, or an empty mask (no foreground pixel) is a missing view for that frame; the
model marginalises it. Foreground = grey value > ``threshold``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from silpose.shared.skeleton import JOINT_NAMES

from .persistence import load_model


class InferenceInputError(ValueError):
    """Bad ``silpose infer`` input; the message names the file or folder."""


def _is_dataset(folder: Path) -> bool:
    return any(folder.glob("*.parquet"))


def read_dataset_input(model, folder: Path, split: str):
    """(frame names (N,), contours (N, K_rig, n, 2) px, views_present (N, K_rig)) from a dataset split."""
    from silpose.shared.dataset import list_shards, load_split

    if not list_shards(folder, split):
        raise InferenceInputError(f"{folder}: no shards of split {split!r} (files {split}-*-of-*.parquet)")
    data = load_split(folder, split, columns=["contours"])
    if data.contours.shape[1] != model.n_rig_views_:
        raise InferenceInputError(
            f"{folder}: the dataset has {data.contours.shape[1]} views, the model's rig has {model.n_rig_views_}"
        )
    if model.rig_ is not None and tuple(data.rig.names) != tuple(model.rig_.names):
        raise InferenceInputError(
            f"{folder}: camera names {list(data.rig.names)} differ from the model's rig {list(model.rig_.names)}"
        )
    frames = np.array([f"{split}-{int(i):06d}" for i in data.sample_id])
    return frames, data.contours, np.ones(data.contours.shape[:2], dtype=bool), data.sample_id


def read_png_input(model, folder: Path, threshold: int = 127):
    """(frame names (N,), contours (N, K_rig, n, 2) px (NaN where missing), views_present (N, K_rig), None)."""
    import cv2

    from silpose.shared.contours import EmptyMaskError, extract_contour

    if model.rig_ is None:
        raise InferenceInputError("the model file stores no rig, so camera folders cannot be named; use a dataset")
    names = list(model.rig_.names)
    subdirs = {p.name for p in folder.iterdir() if p.is_dir()}
    present_dirs = [n for n in names if n in subdirs]
    if not present_dirs:
        raise InferenceInputError(
            f"{folder}: neither a dataset (no .parquet files) nor a PNG folder: expected subfolders named as the "
            f"model's cameras {names}, found {sorted(subdirs) or 'none'}"
        )
    files = {n: {p.stem: p for p in (folder / n).glob("*.png")} for n in present_dirs}
    frames = sorted(set().union(*[set(f) for f in files.values()]))
    if not frames:
        raise InferenceInputError(f"{folder}: the camera folders {present_dirs} hold no .png files")
    n_pts = model.layout_.n_points
    contours = np.full((len(frames), len(names), n_pts, 2), np.nan)
    present = np.zeros((len(frames), len(names)), dtype=bool)
    for k, cam_name in enumerate(names):
        cam = model.rig_[k]
        for i, frame in enumerate(frames):
            path = files.get(cam_name, {}).get(frame)
            if path is None:
                continue
            img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
            if img is None:
                raise InferenceInputError(f"{path}: not a readable image")
            if img.shape != (cam.height, cam.width):
                raise InferenceInputError(
                    f"{path}: image is {img.shape[1]}x{img.shape[0]}, camera {cam_name!r} is {cam.width}x{cam.height}"
                )
            try:
                contours[i, k] = extract_contour(img > threshold, n_pts).points
            except EmptyMaskError:
                continue
            present[i, k] = True
    return np.array(frames), contours, present, None


def _write_atomic(path: Path, write) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_joints(path: Path, frames, result, rig_names, sample_id=None, model_path: str = "") -> None:
    """Joints as Parquet (one row per frame; columns ``<joint>_x/_y/_z`` and ``<joint>_x_std`` ..., metres,
    root-relative, world orientation) or JSON (when ``path`` ends in .json)."""
    n = len(frames)
    names = [rig_names[v] if rig_names else str(v) for v in result.views]
    if path.suffix.lower() == ".json":
        doc = {
            "model": model_path,
            "units": "metres, root-relative (pelvis at the origin), world orientation",
            "joint_names": list(JOINT_NAMES),
            "views": names,
            "frames": [
                {
                    "frame": str(frames[i]),
                    **({"sample_id": int(sample_id[i])} if sample_id is not None else {}),
                    "views_present": [names[k] for k in np.flatnonzero(result.views_present[i])],
                    "joints": result.joints[i].round(6).tolist(),
                    "joint_std": result.joint_std[i].round(6).tolist(),
                    "log_marginal": float(result.log_marginal[i]),
                    "component": int(np.argmax(result.responsibilities[i])),
                }
                for i in range(n)
            ],
        }
        _write_atomic(path, lambda p: p.write_text(json.dumps(doc, indent=1)))
        return
    import pyarrow as pa
    import pyarrow.parquet as pq

    cols: dict = {"frame": pa.array([str(f) for f in frames])}
    if sample_id is not None:
        cols["sample_id"] = pa.array(np.asarray(sample_id, dtype=np.int64))
    cols["n_views_present"] = pa.array(result.views_present.sum(1).astype(np.int32))
    cols["views_present"] = pa.array([",".join(names[k] for k in np.flatnonzero(r)) for r in result.views_present])
    cols["log_marginal"] = pa.array(result.log_marginal)
    cols["component"] = pa.array(np.argmax(result.responsibilities, axis=1).astype(np.int32))
    for j, jn in enumerate(JOINT_NAMES):
        for a, axis in enumerate("xyz"):
            cols[f"{jn}_{axis}"] = pa.array(result.joints[:, j, a].astype(np.float32))
    for j, jn in enumerate(JOINT_NAMES):
        for a, axis in enumerate("xyz"):
            cols[f"{jn}_{axis}_std"] = pa.array(result.joint_std[:, j, a].astype(np.float32))
    meta = {"model": model_path, "units": "metres, root-relative (pelvis at the origin), world orientation",
            "joint_names": list(JOINT_NAMES), "views": names}
    table = pa.table(cols).replace_schema_metadata({b"silpose_infer": json.dumps(meta).encode()})
    _write_atomic(path, lambda p: pq.write_table(table, p, compression="zstd"))


def write_contours(path: Path, frames, result, rig_names) -> None:
    """Reconstructed contours (.npz, no pickle): frames (N,) str, views (K,) str, contours_norm / contours_px
    (N, K, n, 2) (px NaN where the view's normalisation is unknown), views_present (N, K)."""
    names = np.array([rig_names[v] if rig_names else str(v) for v in result.views])

    def write(p):
        with open(p, "wb") as f:
            np.savez(f, frames=np.asarray(frames).astype(str), views=names, contours_norm=result.contours_norm,
                     contours_px=result.contours_px, views_present=result.views_present)

    _write_atomic(path, write)


def run_inference(model_path: Path, input_path: Path, *, out: Path, split: str = "test", save_contours: bool = False,
                  noise_variance: float | None = None, threshold: int = 127) -> str:
    """Load the model, read the input, infer, write outputs; returns a one-line summary."""
    model = load_model(model_path)
    input_path = Path(input_path)
    out = Path(out)
    if out.suffix.lower() not in (".parquet", ".json"):
        raise InferenceInputError(f"{out}: the joints file must end in .parquet or .json")
    if not input_path.is_dir():
        raise InferenceInputError(f"{input_path}: no such folder")
    if _is_dataset(input_path):
        frames, contours, present, sample_id = read_dataset_input(model, input_path, split)
    else:
        frames, contours, present, sample_id = read_png_input(model, input_path, threshold)
    modelled = present[:, list(model.layout_.views)]
    empty = ~modelled.any(axis=1)
    if empty.any():
        raise InferenceInputError(
            f"{input_path}: {int(empty.sum())} frame(s) have no usable silhouette in any modelled view "
            f"(first: {frames[np.flatnonzero(empty)[0]]})"
        )
    result = model.infer(contours, present, noise_variance=noise_variance, input_views=range(model.n_rig_views_))
    rig_names = list(model.rig_.names) if model.rig_ is not None else None
    write_joints(out, frames, result, rig_names, sample_id, str(model_path))
    extra = ""
    if save_contours:
        cpath = out.with_name(out.name.rsplit(".", 1)[0] + ".contours.npz")
        write_contours(cpath, frames, result, rig_names)
        extra = f", contours {cpath}"
    n_missing = int((~modelled).sum())
    return (f"{out}: joints of {len(frames)} frames ({n_missing} missing views marginalised){extra}")
