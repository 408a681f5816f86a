"""Throughput of the whole camera path: frames -> silhouettes -> contours -> joints (4 cameras).

Run: ``uv run --no-sync python -m silpose.eval.bench_frames [--frames 200] [--background 50]
[--data data/default] [--model models/default.npz] [--chunk 32] [--threads 1]``; also the
``frames`` section of ``silpose bench``.

The frames are composited (not timed) from the first ``--frames`` test samples of the dataset
(:mod:`silpose.eval.frames_composite`: textured room, person from the true mask, floor shadow,
noise, flicker) and written as PNG folders, then ``silpose infer --frames``'s pipeline
(:func:`silpose.model.frames_io.run_frames_pipeline`) runs on them with the trained model. Rows:
each stage (background fit, PNG decoding, segmentation, contour extraction, inference) and the
total, as seconds, ms per time step (one frame from each of the K cameras) and time steps per
second; the segmentation row also gives camera frames per second. OpenCV is limited to
``--threads`` threads while timing. Timings are noisy on a shared machine: read the shares.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path


def run_frames_bench(n_frames: int = 200, n_background: int = 50, data: str = "data/default",
                     model: str = "models/default.npz", chunk: int = 32, threads: int = 1, seed: int = 0) -> list[dict]:
    """Time the frames-to-joints path; returns one dict per stage (see the module docstring).

    Keys: stage, seconds, ms_per_step (per time step of K camera frames; per camera frame for the
    background row), steps_per_s, share (of the total, background fit excluded), plus on the total row
    n_steps, n_cameras, mean_iou (segmented vs true masks) and pose_cm (mean, segmented input).
    """
    import cv2
    import numpy as np

    from silpose.app.frames_pipeline import run_frames_pipeline
    from silpose.model.persistence import load_model
    from silpose.shared.dataset import load_split

    from .frames_composite import write_composite_frames
    from silpose.shared.metrics import pose_error_cm

    data, model = Path(data), Path(model)
    if not data.is_dir():
        raise FileNotFoundError(f"{data}: dataset not found (generate it: silpose gen {data.name})")
    if not model.is_file():
        raise FileNotFoundError(f"{model}: model not found (train it: silpose train {data.name})")
    m = load_model(model)
    old = cv2.getNumThreads()
    with tempfile.TemporaryDirectory(prefix="silpose-bench-frames-") as tmp:
        frames = write_composite_frames(data, Path(tmp) / "frames", n=n_frames, n_background=n_background, seed=seed)
        truth = load_split(frames, "test", with_masks=True)
        ious: list[float] = []
        names = list(m.rig_.names)

        def score(ch) -> None:  # runs between chunks, outside every stage's timing
            for c, masks in ch.masks.items():
                t = truth.masks[ch.start : ch.start + len(masks), names.index(c)].astype(bool)
                inter = (masks & t).sum(axis=(1, 2))
                ious.extend((inter / np.maximum((masks | t).sum(axis=(1, 2)), 1)).tolist())

        cv2.setNumThreads(threads)
        try:
            c0, t0 = time.thread_time(), time.perf_counter()
            fr = run_frames_pipeline(m, frames, chunk=chunk, on_chunk=score)
            wall, cpu = time.perf_counter() - t0, time.thread_time() - c0
        finally:
            cv2.setNumThreads(old)
        pose = float(np.nanmean(pose_error_cm(fr.result.joints, truth.joints)))
    n, k = len(fr.frames), len(fr.cameras)
    t = fr.timings
    steady = sum(v for key, v in t.items() if key != "background")
    rows = []
    labels = {"background": f"background fit ({n_background} frames x {k} cameras)", "read": "read PNG frames",
              "segment": "segmentation (BackgroundModel.segment_batch)", "contours": "contour extraction",
              "infer": "inference (ShapeStructureModel.infer)"}
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


def format_table(rows: list[dict]) -> str:
    """Markdown table of :func:`run_frames_bench` rows."""
    lines = ["| stage | seconds | ms per time step | time steps/s | share |", "|---|---:|---:|---:|---:|"]
    for r in rows:
        share = "-" if r["share"] != r["share"] else f"{100 * r['share']:.0f} %"
        lines.append(f"| {r['stage']} | {r['seconds']:.3f} | {r['ms_per_step']:.2f} | {r['steps_per_s']:.1f} | {share} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200, help="time steps (test samples) to composite and run")
    parser.add_argument("--background", type=int, default=50, help="background frames per camera")
    parser.add_argument("--data", default="data/default", help="silhouette dataset with test masks")
    parser.add_argument("--model", default="models/default.npz", help="model trained on that dataset")
    parser.add_argument("--chunk", type=int, default=32, help="frames per pipeline chunk")
    parser.add_argument("--threads", type=int, default=1, help="OpenCV threads while timing")
    parser.add_argument("--quick", action="store_true", help="16 time steps, 10 background frames")
    args = parser.parse_args(argv)
    n, nb = (16, 10) if args.quick else (args.frames, args.background)
    rows = run_frames_bench(n, nb, args.data, args.model, args.chunk, args.threads)
    load = os.getloadavg()
    total = rows[-1]
    print(f"{n} time steps x {total['n_cameras']} cameras from {args.data} with {args.model}; OpenCV threads "
          f"{args.threads}; load average {load[0]:.1f} on {os.cpu_count()} cores (shared machine); mean IoU "
          f"{total['mean_iou']:.3f}, pose error {total['pose_cm']:.2f} cm")
    print(format_table(rows))


if __name__ == "__main__":
    main()
