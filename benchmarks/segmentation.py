"""Throughput of the background subtraction at 320x240 (target: >= 200 frames/s per core).

Run: ``uv run --frozen python -m silpose.segment.bench [--frames 200] [--size 320x240] [--threads 1]``.

Frames come from :func:`silpose.segment.synthetic.render_scene` (textured room, noise, flicker, a
figure with a floor shadow). OpenCV is limited to ``threads`` threads (1 = one core) while timing.
Rows: OpenCV's own ``BackgroundSubtractorMOG2`` with shadow detection (an external reference,
trained on the same background frames, then applied with learning rate 0), our model through the
streaming API (per-frame latency percentiles), the batch API, and two variants (no shadow
rejection; NCC over full windows). Every row also reports the mean mask IoU against the truth.
Timings are noisy on a shared machine: compare the ratios, measured in the same process.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from .background import BackgroundModel
from .synthetic import render_scene


def _iou(pred: np.ndarray, truth: np.ndarray) -> float:
    """Mean over frames of the IoU of (N, H, W) bool masks."""
    inter = (pred & truth).sum(axis=(1, 2))
    union = (pred | truth).sum(axis=(1, 2))
    return float(np.mean(inter / np.maximum(union, 1)))


def _stream(fn, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Apply fn frame by frame; returns masks (N, H, W) bool, per-frame wall seconds (N,) and the
    total CPU seconds of this thread."""
    out = np.empty(frames.shape[:3], bool)
    sec = np.empty(len(frames))
    c0 = time.thread_time()
    for i, f in enumerate(frames):
        t0 = time.perf_counter()
        out[i] = fn(f)
        sec[i] = time.perf_counter() - t0
    return out, sec, time.thread_time() - c0


def _row(method, masks, truth, total_s: float, cpu_s: float, per_frame: np.ndarray | None) -> dict:
    n = len(masks)
    row = {
        "method": method,
        "frames": n,
        "frames_per_s": n / total_s,
        "cpu_frames_per_s": n / cpu_s,
        "ms_per_frame": 1e3 * total_s / n,
        "ms_p50": float(np.percentile(per_frame, 50) * 1e3) if per_frame is not None else float("nan"),
        "ms_p95": float(np.percentile(per_frame, 95) * 1e3) if per_frame is not None else float("nan"),
        "iou": _iou(masks, truth),
    }
    return row


def run_segment_bench(
    n_frames: int = 200, size: tuple[int, int] = (320, 240), n_background: int = 50, threads: int = 1, seed: int = 0
) -> list[dict]:
    """Time the segmentation of ``n_frames`` synthetic frames of ``size`` = (W, H) pixels.

    Returns one dict per method with keys: method, frames, frames_per_s (wall clock),
    cpu_frames_per_s (frames per CPU second of the calling thread: per-core throughput, robust to
    other processes sharing the cores), ms_per_frame (mean wall latency), ms_p50, ms_p95
    (streaming wall latency percentiles; nan for batch rows), iou (mean mask IoU against the true
    masks), ratio_to_mog2 (CPU throughput relative to OpenCV's MOG2, > 1 = faster).
    """
    import cv2

    scene = render_scene(n_background=n_background, n_frames=n_frames, size=size, seed=seed)
    frames, truth = scene.frames, scene.masks
    old_threads = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    rows = []
    try:
        mog = cv2.createBackgroundSubtractorMOG2(history=n_background, varThreshold=16, detectShadows=True)
        for f in scene.background:
            mog.apply(f)
        _stream(lambda f: mog.apply(f, learningRate=0) == 255, frames[:5])  # warm-up
        masks, sec, cpu = _stream(lambda f: mog.apply(f, learningRate=0) == 255, frames)
        rows.append(_row("cv2 MOG2 + shadow detection (reference)", masks, truth, sec.sum(), cpu, sec))

        t0, c0 = time.perf_counter(), time.thread_time()
        model = BackgroundModel().fit(scene.background)
        fit_s, fit_cpu = time.perf_counter() - t0, time.thread_time() - c0
        variants = {
            "BackgroundModel.segment (streaming)": model,
            "  no shadow rejection (ncc_threshold=None)": BackgroundModel(ncc_threshold=None).fit(scene.background),
            "  NCC over full windows (ncc_support='window')": BackgroundModel(ncc_support="window").fit(scene.background),
        }
        for name, m in variants.items():
            _stream(m.segment, frames[:5])
            masks, sec, cpu = _stream(m.segment, frames)
            rows.append(_row(name, masks, truth, sec.sum(), cpu, sec))
            if m is model:
                t0, c0 = time.perf_counter(), time.thread_time()
                batch = model.segment_batch(frames)
                wall, cpu = time.perf_counter() - t0, time.thread_time() - c0
                rows.append(_row("BackgroundModel.segment_batch", batch, truth, wall, cpu, None))
        rows.append(
            {"method": f"BackgroundModel.fit ({n_background} background frames)", "frames": n_background,
             "frames_per_s": n_background / fit_s, "cpu_frames_per_s": n_background / fit_cpu, "ms_per_frame": 1e3 * fit_s / n_background,
             "ms_p50": float("nan"), "ms_p95": float("nan"), "iou": float("nan")}
        )  # fmt: skip
    finally:
        cv2.setNumThreads(old_threads)
    ref = rows[0]["cpu_frames_per_s"]
    for r in rows:
        r["ratio_to_mog2"] = r["cpu_frames_per_s"] / ref
    return rows


def format_table(rows: list[dict]) -> str:
    """Markdown table of :func:`run_segment_bench` rows."""
    lines = [
        "| method | frames/s (wall) | frames/CPU-s | ms/frame mean | p50 | p95 | CPU ratio to MOG2 | mean IoU |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    fmt = lambda v, spec: "-" if v != v else format(v, spec)  # nan -> "-"
    for r in rows:
        lines.append(
            f"| {r['method']} | {r['frames_per_s']:.0f} | {r['cpu_frames_per_s']:.0f} | {r['ms_per_frame']:.2f} | {fmt(r['ms_p50'], '.2f')} | "
            f"{fmt(r['ms_p95'], '.2f')} | {r['ratio_to_mog2']:.2f} | {fmt(r['iou'], '.3f')} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--background", type=int, default=50)
    parser.add_argument("--size", default="320x240", help="WxH in pixels")
    parser.add_argument("--threads", type=int, default=1, help="OpenCV threads while timing (1 = per core)")
    args = parser.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))
    rows = run_segment_bench(args.frames, (w, h), args.background, args.threads)
    load = os.getloadavg()
    print(
        f"{args.frames} frames {w}x{h}, {args.background} background frames, OpenCV threads {args.threads}, "
        f"load average {load[0]:.1f} on {os.cpu_count()} cores (shared machine)"
    )
    print(format_table(rows))


if __name__ == "__main__":
    main()
