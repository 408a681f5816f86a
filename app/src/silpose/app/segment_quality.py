"""Segmentation quality of :class:`silpose.segment.BackgroundModel` on a rendered frames dataset (measurement tool).

``python -m silpose.app.segment_quality data/smoke/frames [--set name=value ...]`` fits one
background model per camera from ``background/<camera>/``, segments ``frames/<camera>/`` and
compares with the truth split ``test`` of the same folder (row i = frame i; read with
:func:`silpose.shared.dataset.load_split`). Per view (frame, camera) it prints:

- ``iou``: ``|S & T| / |S | T|`` of the segmented mask S and the true mask T
  (:func:`silpose.shared.metrics.mask_iou`);
- ``fp_out``: pixels of S outside T grown by ``--grow`` px (default 2; an elliptical dilation),
  i.e. shadow / background errors rather than boundary disagreement;
- ``person_iou``: the IoU of ``S & grow(T)`` with T: the quality of the person's own outline once
  the errors away from it are discounted;

for the final mask and, with ``--stages``, for the ``candidates`` and ``shadow_rejected`` stages
too (false positives outside the grown truth). Means over all views close the table.
``--set`` overrides a :class:`BackgroundModel` parameter (Python literal: ``--set
ncc_threshold=None --set median_size=3``).
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

import cv2
import numpy as np

from silpose.segment import BackgroundModel
from silpose.shared.dataset import load_split
from silpose.shared.metrics import mask_iou

from .recordings.frames_source import open_frames_folder
from .recordings.sources import CameraReader, open_recording

#: frames segmented at once
CHUNK = 64


def grow(mask: np.ndarray, px: int) -> np.ndarray:
    """Dilate an (H, W) bool mask by ``px`` pixels (elliptical element of side 2 px + 1); px <= 0: unchanged."""
    if px <= 0:
        return mask.astype(bool)
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * px + 1, 2 * px + 1))
    return cv2.dilate(mask.astype(np.uint8), k) > 0


def view_scores(seg: np.ndarray, truth: np.ndarray, grow_px: int = 2) -> dict[str, float]:
    """Scores of one (H, W) bool segmentation vs its (H, W) bool truth: iou, fp_out, person_iou."""
    seg, truth = seg.astype(bool), truth.astype(bool)
    near = grow(truth, grow_px)
    return {
        "iou": mask_iou(seg, truth),
        "fp_out": float(np.count_nonzero(seg & ~near)),
        "person_iou": mask_iou(seg & near, truth),
    }


def evaluate(frames_dir, params: dict | None = None, grow_px: int = 2, stages: bool = False) -> list[dict]:
    """Segment every view of a frames dataset and score it against the truth.

    Returns one dict per (frame, camera): ``frame`` (int), ``camera`` (str), the
    :func:`view_scores` of the final mask, and with ``stages`` ``fp_out_<stage>`` for the
    ``candidates`` and ``shadow_rejected`` stages.
    """
    frames_dir = Path(frames_dir)
    truth = load_split(frames_dir, "test", with_masks=True)
    cams = list(truth.rig.names)
    folder = open_frames_folder(frames_dir, truth.rig)
    if len(folder.frame_names) != len(truth):
        raise SystemExit(f"{frames_dir}: {len(folder.frame_names)} frames but {len(truth)} truth rows")
    backgrounds = open_recording(folder.background, truth.rig, role="background").sources
    rows = []
    for cam, source in folder.recording.sources.items():
        k = cams.index(cam)
        model = BackgroundModel(**(params or {}))
        for _, chunk in _chunks(backgrounds[cam]):
            model.partial_fit(chunk)
        for start, chunk in _chunks(source):
            out = model.segment_batch(chunk, return_stages=True)
            for i in range(len(chunk)):
                j = start + i
                t = truth.masks[j, k] > 0
                row = {"frame": j, "camera": cam, **view_scores(out["final"][i], t, grow_px)}
                if stages:
                    near = grow(t, grow_px)
                    for s in ("candidates", "shadow_rejected"):
                        row[f"fp_out_{s}"] = float(np.count_nonzero(out[s][i] & ~near))
                rows.append(row)
    rows.sort(key=lambda r: (r["frame"], cams.index(r["camera"])))
    return rows


def _chunks(source):
    """Yield (start, (n, H, W, 3) uint8 BGR frames) of a camera source, :data:`CHUNK` frames at a time."""
    reader = CameraReader(source, grey=False)
    try:
        start, frames = 0, []
        while (img := reader.read()) is not None:
            frames.append(img)
            if len(frames) == CHUNK:
                yield start, np.stack(frames)
                start, frames = start + CHUNK, []
        if frames:
            yield start, np.stack(frames)
    finally:
        reader.close()


def _parse_set(items: list[str]) -> dict:
    out = {}
    for item in items:
        if "=" not in item:
            raise SystemExit(f"--set {item!r}: expected name=value")
        name, value = item.split("=", 1)
        try:
            out[name.strip()] = ast.literal_eval(value.strip())
        except (ValueError, SyntaxError):
            raise SystemExit(f"--set {item!r}: the value must be a Python literal (number, None, tuple, string)")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m silpose.app.segment_quality",
        description="Score BackgroundModel on a frames dataset with truth masks: per-view IoU, false-positive "
        "pixels outside the truth grown by --grow px, and the person-only IoU (see the module docstring).",
    )
    p.add_argument("frames_dir", help="frames dataset folder (background/, frames/, test-*.parquet)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="override a BackgroundModel parameter (Python literal); repeatable")
    p.add_argument("--grow", type=int, default=2, help="pixels the truth is grown by for fp_out / person_iou (default 2)")
    p.add_argument("--stages", action="store_true", help="also count fp_out for the candidates and shadow_rejected stages")
    p.add_argument("--quiet", action="store_true", help="print only the means")
    a = p.parse_args(argv)
    rows = evaluate(a.frames_dir, _parse_set(a.set), a.grow, a.stages)
    keys = [k for k in rows[0] if k not in ("frame", "camera")]
    if not a.quiet:
        print("frame camera " + " ".join(f"{k:>22s}" for k in keys))
        for r in rows:
            print(f"{r['frame']:5d} {r['camera']:>6s} " + " ".join(f"{r[k]:22.3f}" for k in keys))
    means = {k: float(np.mean([r[k] for r in rows])) for k in keys}
    sums = {k: float(np.sum([r[k] for r in rows])) for k in keys if k.startswith("fp_out")}
    print(f"views {len(rows)}; mean " + ", ".join(f"{k} {v:.3f}" for k, v in means.items()))
    print("total " + ", ".join(f"{k} {v:.0f}" for k, v in sums.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
