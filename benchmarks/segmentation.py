"""Throughput of the background subtraction at 320x240 (target: >= 200 frames/s per core), and at full HD
against MOG2 on the same frames (:func:`run_full_hd`; target: at most 1.5x MOG2's time at the same resolution,
IoU >= MOG2's), and on textured frames rendered by Blender (:func:`run_rendered`).

Section ``segmentation`` of ``python -m benchmarks.run``.

Frames come from :func:`silpose.segment.synthetic.render_scene` (textured room, noise, flicker, a
figure with a floor shadow). OpenCV is limited to ``threads`` threads (1 = one core) while timing.
Rows: OpenCV's own ``BackgroundSubtractorMOG2`` with shadow detection (an external reference,
trained on the same background frames, then applied with learning rate 0), our model through the
streaming API (per-frame latency percentiles), the batch API, and two variants (no shadow
rejection; NCC over full windows). Every row also reports the mean mask IoU against the truth.

Timings are noisy on a shared machine: every streaming row passes over its frames ``repeats`` times and keeps,
frame by frame, the fastest pass (wall and CPU seconds alike: a pass slowed by another process is dropped); the
methods compared alternate pass by pass. Compare the ratios, measured in the same process: ``same_size_mog2`` names
the MOG2 row at the same resolution, ``time_vs_same_size_mog2`` is the row's CPU time over that row's (the issue's
"x slower": target <= 1.5) and ``iou_minus_same_size_mog2`` the IoU difference (target >= 0).
"""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np

from silpose.segment import BackgroundModel
from silpose.segment.synthetic import render_scene
from silpose.shared.metrics import mask_iou


def _stream(fn, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Apply fn frame by frame; returns masks (N, H, W) bool and per-frame wall and CPU (this thread) seconds (N,)."""
    out = np.empty(frames.shape[:3], bool)
    sec = np.empty(len(frames))
    cpu = np.empty(len(frames))
    for i, f in enumerate(frames):
        t0, c0 = time.perf_counter(), time.thread_time()
        out[i] = fn(f)
        sec[i], cpu[i] = time.perf_counter() - t0, time.thread_time() - c0
    return out, sec, cpu


def _best_of(fns: dict, frames: np.ndarray, repeats: int) -> dict:
    """Each of ``fns`` (name -> per-frame function) over ``frames``, ``repeats`` passes alternating between the
    functions; name -> (masks of the last pass, fastest wall seconds per frame (N,), fastest CPU seconds per frame)."""
    best = {}
    for _ in range(max(1, repeats)):
        for name, fn in fns.items():
            masks, sec, cpu = _stream(fn, frames)
            if name in best:
                sec, cpu = np.minimum(best[name][1], sec), np.minimum(best[name][2], cpu)
            best[name] = (masks, sec, cpu)
    return best


def _row(method, masks, truth, total_s: float, cpu_s: float, per_frame: np.ndarray | None) -> dict:
    n = len(masks)
    row = {
        "method": method,
        "frames": n,
        "seconds": total_s,
        "cpu_s": cpu_s,
        "frames_per_s": n / total_s,
        "cpu_frames_per_s": n / cpu_s,
        "ms_per_frame": 1e3 * total_s / n,
        "ms_p50": float(np.percentile(per_frame, 50) * 1e3) if per_frame is not None else float("nan"),
        "ms_p95": float(np.percentile(per_frame, 95) * 1e3) if per_frame is not None else float("nan"),
        "iou": float(np.mean(mask_iou(masks, truth))),
    }
    return row


def _best_row(method: str, best: tuple, truth: np.ndarray) -> dict:
    masks, sec, cpu = best
    return _row(method, masks, truth, float(sec.sum()), float(cpu.sum()), sec)


def _mog2(background: np.ndarray):
    """OpenCV's MOG2 with shadow detection learnt on ``background`` frames; returns the per-frame mask function
    (learning rate 0: the model stays as learnt, so passes over the frames are repeatable)."""
    mog = cv2.createBackgroundSubtractorMOG2(history=len(background), varThreshold=16, detectShadows=True)
    for f in background:
        mog.apply(f)
    return lambda f: mog.apply(f, learningRate=0) == 255  # noqa: E731


def _same_size(rows: list[dict], ref: dict, names: list[str]) -> None:
    """Adds the same-resolution comparison with the MOG2 row ``ref`` to the rows named ``names``."""
    for r in rows:
        if r["method"] in names:
            r["same_size_mog2"] = ref["method"]
            r["time_vs_same_size_mog2"] = r["cpu_s"] / r["frames"] / (ref["cpu_s"] / ref["frames"])
            r["iou_minus_same_size_mog2"] = r["iou"] - ref["iou"]


def run(
    n_frames: int = 200, size: tuple[int, int] = (320, 240), n_background: int = 50, threads: int = 1, seed: int = 0,
    hd_frames: int = 20, repeats: int = 3, rendered: str | bool | None = None,
) -> list[dict]:
    """Time the segmentation of ``n_frames`` synthetic frames of ``size`` = (W, H) pixels, ``repeats`` passes
    (the fastest per frame, module docstring).

    Returns one dict per method with keys: method, frames, seconds (wall), cpu_s (CPU seconds of the
    calling thread), frames_per_s (wall clock), cpu_frames_per_s (frames per CPU second of the
    calling thread: per-core throughput, robust to other processes sharing the cores), ms_per_frame (mean wall latency), ms_p50, ms_p95
    (streaming wall latency percentiles; nan for batch rows), iou (mean mask IoU against the true
    masks), ratio_to_mog2 (cpu_frames_per_s relative to that of OpenCV's MOG2 row, > 1 = faster); the
    BackgroundModel streaming rows also same_size_mog2, time_vs_same_size_mog2 and iou_minus_same_size_mog2.
    rendered: a frames dataset for :func:`run_rendered` (None: the first of :data:`RENDERED`; False: none).
    """
    scene = render_scene(n_background=n_background, n_frames=n_frames, size=size, seed=seed)
    frames, truth = scene.frames, scene.masks
    old_threads = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    rows = []
    try:
        mog_name = "cv2 MOG2 + shadow detection (reference)"
        t0, c0 = time.perf_counter(), time.thread_time()
        model = BackgroundModel().fit(scene.background)
        fit_s, fit_cpu = time.perf_counter() - t0, time.thread_time() - c0
        fns = {
            mog_name: _mog2(scene.background),
            "BackgroundModel.segment (streaming)": model.segment,
            "  no shadow rejection (ncc_threshold=None)": BackgroundModel(ncc_threshold=None).fit(scene.background).segment,
            "  NCC over full windows (ncc_support='window')": BackgroundModel(ncc_support="window").fit(scene.background).segment,
        }
        _best_of(fns, frames[:5], 1)  # warm-up
        best = _best_of(fns, frames, repeats)
        for name in fns:
            rows.append(_best_row(name, best[name], truth))
            if name == "BackgroundModel.segment (streaming)":
                wall = cpu = float("inf")
                for _ in range(max(1, repeats)):  # the fastest of the passes, as the streaming rows
                    t0, c0 = time.perf_counter(), time.thread_time()
                    batch = model.segment_batch(frames)
                    wall, cpu = min(wall, time.perf_counter() - t0), min(cpu, time.thread_time() - c0)
                rows.append(_row("BackgroundModel.segment_batch", batch, truth, wall, cpu, None))
        rows.append(
            {"method": f"BackgroundModel.fit ({n_background} background frames)", "frames": n_background,
             "seconds": fit_s, "cpu_s": fit_cpu, "frames_per_s": n_background / fit_s,
             "cpu_frames_per_s": n_background / fit_cpu, "ms_per_frame": 1e3 * fit_s / n_background,
             "ms_p50": float("nan"), "ms_p95": float("nan"), "iou": float("nan")}
        )  # fmt: skip
    finally:
        cv2.setNumThreads(old_threads)
    ref = rows[0]["cpu_frames_per_s"]
    for r in rows:
        r["ratio_to_mog2"] = r["cpu_frames_per_s"] / ref
    _same_size(rows, rows[0], [n for n in fns if n != mog_name] + ["BackgroundModel.segment_batch"])
    if hd_frames > 0:
        rows += run_full_hd(hd_frames, n_background=min(n_background, 20), threads=threads, seed=seed, repeats=repeats)
    if rendered is not False:
        rows += run_rendered(rendered or None, repeats=repeats)
    return rows


def run_full_hd(n_frames: int = 20, n_background: int = 20, threads: int = 1, seed: int = 0, repeats: int = 3) -> list[dict]:
    """1920x1080 frames (a person ~850 px tall): OpenCV's MOG2 on the full frames (the reference) vs the
    recordings pipeline's segmentation -- the frame resized (``cv2.INTER_AREA``) to the working size where the
    person is :data:`~silpose.app.recordings.resolution.WORK_PERSON_PX` tall, the paper's background
    subtraction with the lighting gain, the mask scaled back (bilinear, threshold at half) -- timed per frame
    (resize included) and scored at full size against the truth. ``ratio_to_mog2`` as in :func:`run`;
    ``time_vs_mog2`` is its inverse (the issue's "x slower"). More rows at the working size, scored the
    same way, say what the working size itself costs: MOG2 on the same shrunk frames, and the true masks
    shrunk and scaled back (the best any mask at that size can score); two rows time the two subtractions alone
    on frames shrunk beforehand (no resize in the timing: their own same-size ratio). BackgroundModel at full
    size runs on the first 5 frames, against MOG2 at full size on the same 5 (a row of its own). Every row
    keeps the fastest of ``repeats`` passes per frame; the same-size columns are those of :func:`run`."""
    from silpose.app.recordings.resolution import WORK_PERSON_PX, shrink

    scene = render_scene(n_background=n_background, n_frames=n_frames, size=(1920, 1080), seed=seed)
    frames, truth = scene.frames, scene.masks
    rows_any = np.flatnonzero(truth.any(axis=2).any(axis=0))
    person_px = float(rows_any.max() - rows_any.min() + 1)
    s = min(1.0, WORK_PERSON_PX / person_px)
    size = (int(round(1920 * s)), int(round(1080 * s)))
    old_threads = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    rows = []
    try:
        small = lambda f: shrink(f, size)  # noqa: E731  (the recordings pipeline's resize)
        up = lambda m: cv2.resize(m.view(np.uint8) * np.uint8(255), (1920, 1080), interpolation=cv2.INTER_LINEAR) > 127  # noqa: E731
        small_background = np.stack([small(b) for b in scene.background])
        model = BackgroundModel(gain=True).fit(small_background)
        mog_small = _mog2(small_background)
        at = f"the working size {size[0]}x{size[1]} (person {person_px:.0f} -> {person_px * s:.0f} px)"
        names = {
            "mog_full": "1920x1080: cv2 MOG2 + shadow detection, full size (reference)",
            "bm_work": f"1920x1080: BackgroundModel at {at}",
            "mog_work": f"1920x1080: cv2 MOG2 + shadow detection at {at}",
        }
        best = _best_of({
            names["mog_full"]: _mog2(scene.background),
            names["bm_work"]: lambda f: up(model.segment(small(f))),
            names["mog_work"]: lambda f: up(mog_small(small(f))),
        }, frames, repeats)  # fmt: skip
        rows += [_best_row(n, best[n], truth) for n in names.values()]
        truth_name = f"1920x1080: the true masks shrunk to {at} and back"
        rows.append(_best_row(truth_name, _best_of({0: lambda t: up(small(t.view(np.uint8) * np.uint8(255)) > 127)},
                                                     truth, repeats)[0], truth))
        # the two subtractions alone, on frames shrunk beforehand (scored at the working size against the truth shrunk
        # the same way and thresholded at half)
        shrunk = np.stack([small(f) for f in frames])
        shrunk_truth = np.stack([small(t.view(np.uint8) * np.uint8(255)) > 127 for t in truth])
        alone = {
            "bm_alone": f"1920x1080 shrunk beforehand: BackgroundModel.segment alone at {size[0]}x{size[1]}",
            "mog_alone": f"1920x1080 shrunk beforehand: cv2 MOG2 alone at {size[0]}x{size[1]}",
        }
        best = _best_of({alone["mog_alone"]: mog_small, alone["bm_alone"]: model.segment}, shrunk, repeats)
        rows += [_best_row(n, best[n], shrunk_truth) for n in (alone["mog_alone"], alone["bm_alone"])]
        n = min(5, n_frames)
        full = BackgroundModel(gain=True).fit(scene.background)
        full_names = {
            "mog": f"1920x1080: cv2 MOG2 + shadow detection, full size, first {n} frames",
            "bm": f"1920x1080: BackgroundModel at full size, first {n} frames",
        }
        best = _best_of({full_names["mog"]: _mog2(scene.background), full_names["bm"]: full.segment}, frames[:n],
                        repeats)
        rows += [_best_row(name, best[name], truth[:n]) for name in full_names.values()]
    finally:
        cv2.setNumThreads(old_threads)
    ref = rows[0]["cpu_frames_per_s"]
    for r in rows:
        r["ratio_to_mog2"] = r["cpu_frames_per_s"] / ref
        r["time_vs_mog2"] = ref / r["cpu_frames_per_s"]
    by = {r["method"]: r for r in rows}
    _same_size(rows, by[names["mog_work"]], [names["bm_work"]])
    _same_size(rows, by[alone["mog_alone"]], [alone["bm_alone"]])
    _same_size(rows, by[full_names["mog"]], [full_names["bm"]])
    return rows


#: frames datasets (``silpose gen-frames``) :func:`run_rendered` looks for, in this order, when given none
RENDERED = ("data/smoke/frames", "data/default/frames")


def run_rendered(frames_dir: str | None = None, repeats: int = 3) -> list[dict]:
    """The background subtraction on a frames dataset rendered by Blender (``just frames``: a textured room with
    props, floor shadows, camera noise and flicker; the truth masks of its test split), camera by camera, against
    MOG2 on the same frames: each learns that camera's empty-room frames. Unlike :func:`render_scene`'s flat
    figure, these people cast soft shadows on a textured floor and their clothes can match the room, which is
    what the shadow rules and the clean-up are for. ``frames_dir`` None: the first of :data:`RENDERED` that
    exists; none: one row saying so. The rows as :func:`run`'s (the fastest of ``repeats`` passes per frame,
    CPU time summed over the cameras), with the same-size columns."""
    from silpose.app.recordings.frames_source import open_frames_folder
    from silpose.app.recordings.sources import CameraReader, open_recording
    from silpose.shared.dataset import load_split

    folder = Path(frames_dir) if frames_dir else next((Path(p) for p in RENDERED if Path(p).is_dir()), None)
    if folder is None or not folder.is_dir():
        return [{"method": "rendered frames: not run", "skipped": f"no frames dataset ({', '.join(RENDERED)}): "
                 "`just frames smoke` renders one"}]

    def read(source) -> np.ndarray:
        reader = CameraReader(source, grey=False)
        try:
            out = []
            while (img := reader.read()) is not None:
                out.append(img)
            return np.stack(out)
        finally:
            reader.close()

    truth = load_split(folder, "test", with_masks=True)
    frames = open_frames_folder(folder, truth.rig)
    backgrounds = open_recording(frames.background, truth.rig, role="background").sources
    names = list(truth.rig.names)
    shape = truth.masks.shape[-2:]
    mog_name = f"rendered frames {shape[1]}x{shape[0]} ({folder}): cv2 MOG2 + shadow detection"
    bm_name = f"rendered frames {shape[1]}x{shape[0]} ({folder}): BackgroundModel.segment"
    parts: dict[str, list] = {mog_name: [], bm_name: []}
    old_threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        for cam, source in frames.recording.sources.items():
            views, background = read(source), read(backgrounds[cam])
            best = _best_of({mog_name: _mog2(background), bm_name: BackgroundModel().fit(background).segment},
                            views, repeats)
            t = truth.masks[: len(views), names.index(cam)] > 0
            for name in parts:
                parts[name].append((*best[name], t))
    finally:
        cv2.setNumThreads(old_threads)
    rows = []
    for name, got in parts.items():
        masks, sec, cpu, t = (np.concatenate(x) for x in zip(*got))
        rows.append(_row(name, masks, t, float(sec.sum()), float(cpu.sum()), sec))
    _same_size(rows, rows[0], [bm_name])
    return rows
