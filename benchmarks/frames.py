"""Throughput of the whole camera path: frames -> silhouettes -> contours -> joints (4 cameras).

Section ``frames`` of ``python -m benchmarks.run``.

The frames are composited (not timed) from the first ``n_frames`` test samples of the dataset
(:func:`benchmarks.frames_composite.write_composite_frames`: textured room, person from the true
mask, floor shadow, noise, flicker) and written as PNG folders, then ``silpose infer --frames``'s
pipeline (:func:`silpose.app.recordings.one_person.run_one_person`, one thread: the stages are timed apart)
runs on them with the trained model, with the plain posterior (no robust inference, no hypotheses: the
rows stay comparable with earlier reports; ``silpose infer --frames`` adds both). Rows: each stage (background fit, PNG decoding, segmentation, blobs and
contour extraction, inference) and the total, as seconds, ms per
time step (one frame from each of the K cameras) and time steps per second; the segmentation row also
gives camera frames per second. OpenCV is limited to ``threads`` threads while timing. Without the
dataset or model, see :mod:`benchmarks.inputs` (``fallback``). Timings are noisy on a shared machine:
read the shares.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from benchmarks.frames_composite import write_composite_frames
from silpose.model import load_model
from silpose.app.recordings.one_person import run_one_person
from silpose.app.recordings.pipeline import RecordingOptions
from silpose.shared.dataset import load_split
from silpose.shared.metrics import mask_iou, pose_error_cm

from . import inputs


def run(n_frames: int = 200, n_background: int = 50, data: str = "data/default", model: str = "models/default.npz",
        chunk: int = 32, threads: int = 1, seed: int = 0, fallback: str = "skip") -> list[dict]:
    """Time the frames-to-joints path; returns one dict per stage (see the module docstring).

    Keys: stage, seconds, ms_per_step (per time step of K camera frames; per camera frame for the
    background row), steps_per_s, share (of the total, background fit excluded), plus on the total row
    n_steps, n_cameras, mean_iou (segmented vs true masks), pose_cm (mean, segmented input) and data
    (what was measured). Without ``data`` or ``model``: :func:`benchmarks.inputs.resolve`.
    """
    with tempfile.TemporaryDirectory(prefix="silpose-bench-frames-") as tmp:
        src = inputs.resolve("frames", data, model, fallback, Path(tmp))
        if src.skip:
            return [inputs.skip_row("frames", src.skip)]
        rows = _measure(src, Path(tmp) / "frames", n_frames, n_background, chunk, threads, seed)
    rows[-1]["data"] = src.label
    return rows


def _measure(src: inputs.Inputs, frames_dir: Path, n_frames: int, n_background: int, chunk: int, threads: int,
             seed: int) -> list[dict]:
    """Composite the frames into ``frames_dir``, run the pipeline timed, return the rows (see :func:`run`)."""
    m = load_model(src.model)
    frames = write_composite_frames(src.data, frames_dir, n=n_frames, n_background=n_background, seed=seed)
    truth = load_split(frames, "test", with_masks=True)
    ious: list[float] = []
    names = list(m.rig_.names)

    def score(ch) -> None:  # runs between chunks, outside every stage's timing
        for c, masks in ch.masks.items():
            t = truth.masks[ch.start : ch.start + len(masks), names.index(c)]
            ious.extend(mask_iou(masks, t).tolist())

    old = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    try:
        c0, t0 = time.thread_time(), time.perf_counter()
        opt = RecordingOptions(overlays=False, chunk=chunk, threads=0, work_person_px=0, robust=False, hypotheses=0)
        fr = run_one_person(m, frames, opt, frames_layout=True, temporal=False, on_chunk=score)
        wall, cpu = time.perf_counter() - t0, time.thread_time() - c0
    finally:
        cv2.setNumThreads(old)
    pose = float(np.nanmean(pose_error_cm(fr.result.joints, truth.joints)))
    n, k = len(fr.frames), len(fr.cameras)
    t = fr.timings
    steady = sum(v for key, v in t.items() if key not in ("background", "overlays"))
    rows = []
    labels = {"background": f"background fit ({n_background} frames x {k} cameras)", "read": "read PNG frames",
              "segment": "segmentation (BackgroundModel.segment)", "contours": "blobs and contour extraction",
              "infer": "inference (ShapeStructureModel.infer)",
              "place": "placement in the room and the silhouette fit"}
    for key, label in labels.items():
        sec = t[key]
        per = n_background * k if key == "background" else n
        row = {"stage": label, "seconds": sec, "ms_per_step": 1e3 * sec / per, "steps_per_s": per / sec if sec else float("inf"),
               "share": float("nan") if key == "background" else sec / steady}
        if key == "segment":
            row["camera_frames_per_s"] = n * k / sec if sec else float("inf")
        rows.append(row)
    rows.append({"stage": f"frames -> joints total ({k} cameras, background fit excluded)", "seconds": steady,
                 "ms_per_step": 1e3 * steady / n, "steps_per_s": n / steady, "share": 1.0, "n_steps": n,
                 "n_cameras": k, "wall_s_incl_background": wall, "cpu_s_this_thread": cpu,
                 "mean_iou": float(np.mean(ious)), "pose_cm": pose})
    return rows
