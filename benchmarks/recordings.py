"""Recordings (``silpose infer --videos``): time steps per second, memory over a 10x longer video, accuracy.

Section ``recordings`` of ``python -m benchmarks.run``. Inputs, made in a temporary folder (not timed):
the lab recording of :mod:`silpose.datagen.lab` (two walkers crossing in front of four 644x486 cameras
on one wall, ``n_frames`` frames, lossy mask videos) and a model of the lab rig (``model``, or trained on
``train`` walkers rendered for the lab rig with the real generator and trainer). The long recording
plays the mask videos ``repeat`` times, forwards then backwards (so the walkers never jump), re-encoded.

Rows:

- ``run``: one per measured run, each in its own Python subprocess: steps, wall seconds and time steps
  per second, the steady rate between the first step and the last (``steady_steps_per_s``: without the run's
  ``setup_s`` -- opening the videos, learning backgrounds -- and ``finish_s`` -- closing the files, the floor
  plan; what a long recording approaches), CPU seconds per step (all threads; the machine is shared, so wall time is the noisier
  figure), per-stage shares, the process's baseline RSS (after imports and the model) and peak RSS
  (``VmHWM`` of ``/proc/self/status``: ``getrusage``'s ``ru_maxrss`` is not reset by ``exec``, so a
  child would report the peak of the process that forked it when that was larger). Runs: 1x and ``repeat`` x without overlays
  (``silpose infer --videos --masks``'s defaults: top-3 hypotheses, no robust inference), ``repeat`` x with ``--robust``,
  1x single-threaded (no camera pool, no reader threads), 1x and ``repeat`` x with overlay videos (with ``overlay_share_wall`` /
  ``overlay_share_cpu``: the overlays' share against the plain run of the same length, :func:`_overlay_shares`; the
  long run spreads the worker's start -- a fresh Python importing OpenCV, ~0.25 CPU s -- over ``repeat`` times the
  steps), 1x carved (``carve=True``: views cut to the people's visual
  hulls, :mod:`silpose.app.recordings.hull`, off by default for mask videos; its ``steps_vs_1x`` and ``cpu_vs_1x``
  are the ratios against the 1x run), 1x without the silhouette fit (``silhouette_fit=False``,
  :mod:`silpose.app.recordings.silhouette_fit`); and (``colour``) the first ``colour_frames`` steps as colour videos
  at ``colour_scale`` x the lab's size (:func:`_colour_recording`), without and with overlays, next to their
  references in the same run (row ``reference``, :func:`decode_reference`: decoding alone, OpenCV's MOG2 alone,
  and the pipeline's shrinking to the working size and segmentation alone, CPU ms per step).
- ``accuracy``: the 1x run (and the 1x carved run, and the run without the silhouette fit) against the truth
  (:mod:`benchmarks.recording_scores`): people, identity switches, person-frames with >= 1..4 usable views, root /
  world-frame / root-relative errors, the share of joints inside the walker's own silhouette in the views used
  (``joints_inside``, 2 px); and the same walkers
  inferred from clean per-person masks.
- ``floor``: finding people on the floor, the occupancy grid (:mod:`silpose.app.recordings.floor`) vs the
  blobs' foot points through each camera's floor homography (:func:`foot_points`, the alternative): per
  frame, detections paired with the true pelvis (Hungarian, 0.5 m gate): recall, false detections, error.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from . import subproc

TINY_TRAIN, TINY_MODEL = 120, {"n_components": 2, "n_latent": 8, "max_iter": 30, "n_init": 1}
MODEL = {"n_components": 5, "n_latent": 20, "max_iter": 100, "n_init": 1}


def _train(folder: Path, n_train: int, n_points: int, hyper: dict) -> Path:
    from silpose.app.training import run_training
    from silpose.datagen.config import load_config
    from silpose.datagen.lab import lab_rig
    from silpose.datagen.pipeline import generate

    (folder / "lab_rig.json").write_text(lab_rig().to_json())
    (folder / "lab.toml").write_text(
        f'name = "lab"\nseed = 0\nrenderer = "raster"\nshard_size = 100\nn_points = {n_points}\nmax_redraws = 50\n'
        f'[splits]\ntrain = {n_train}\ntest = 0\n[rig]\nfile = "lab_rig.json"\n')
    generate(load_config(folder / "lab.toml"), folder / "data", workers=2, progress=False)
    out = folder / "lab.npz"
    run_training(str(folder / "data"), out=out, progress=False, **hyper)
    return out


def _ping_pong(src: Path, dst: Path, repeat: int) -> int:
    """Write ``dst/<camera>.mp4``: each of ``src``'s mask videos played ``repeat`` times, forwards then
    backwards. Returns the frame count."""
    import cv2
    import numpy as np

    dst.mkdir(parents=True, exist_ok=True)
    n = 0
    for video in sorted(src.glob("*.mp4")):
        cap = cv2.VideoCapture(str(video))
        fps = cap.get(cv2.CAP_PROP_FPS)
        frames = []
        while True:
            ok, img = cap.read()
            if not ok:
                break
            frames.append(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY))
        cap.release()
        h, w = frames[0].shape
        wr = cv2.VideoWriter(str(dst / video.name), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h), isColor=False)
        order = [i if r % 2 == 0 else len(frames) - 1 - i for r in range(repeat) for i in range(len(frames))]
        for i in order:
            wr.write(np.ascontiguousarray(frames[i]))
        wr.release()
        n = len(order)
    return n


def _colour_recording(lab: Path, dst: Path, size: tuple[int, int], model: str, n_frames: int,
                      n_background: int = 20) -> tuple[Path, Path, str]:
    """Colour videos of the lab recording at ``size`` (width, height; 1932x1458 is 3x the lab cameras' size, more
    pixels than 1080p; 1920x1080 stretches the lab's 4:3 pictures to 16:9, a camera with non-square pixels): the
    walkers' true masks resized and composited over a textured room with floor shadows and noise
    (:mod:`silpose.segment.composite`), an empty-room clip per camera, and the model with its rig scaled to that
    size; the first ``n_frames`` frames. Returns (videos, clips, model file)."""
    import cv2
    import numpy as np

    import dataclasses

    from silpose.datagen.lab import LAB_FPS, unpack_masks
    from silpose.model.persistence import load_model, save_model
    from silpose.segment.composite import background_frames, composite_frame, room
    from silpose.shared.camera import Rig

    masks = unpack_masks(np.load(lab / "truth.npz")).any(axis=1)[:n_frames]  # (T, K, H, W)
    m = load_model(model)
    rig = m.rig_
    def scaled(c):  # c's pictures resized to ``size`` (pixel centres: (x + 0.5) s - 0.5 on each axis)
        s = np.array([size[0] / c.width, size[1] / c.height])
        K = np.array(c.K, float)
        K[:2] *= s[:, None]
        K[:2, 2] += 0.5 * s - 0.5
        return dataclasses.replace(c, K=K, width=int(size[0]), height=int(size[1]))

    big = [scaled(c) for c in rig]
    videos, clips = dst / "colour", dst / "empty"
    videos.mkdir(parents=True, exist_ok=True)
    clips.mkdir(parents=True, exist_ok=True)
    for k, cam in enumerate(big):
        size = (cam.width, cam.height)
        clean = room(k, size)
        for path, frames in ((videos / f"{cam.name}.mp4",
                              (composite_frame(cv2.resize(masks[f, k].view(np.uint8), size, interpolation=cv2.INTER_NEAREST),
                                               k, f, clean=clean) for f in range(len(masks)))),
                             (clips / f"{cam.name}.mp4", iter(background_frames(k, size, n_background)))):
            w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), LAB_FPS, size)
            for f in frames:
                w.write(f)
            w.release()
    m.rig_ = Rig(tuple(big), rig.transform, rig.workspace, rig.source)
    out = dst / "model-big.npz"
    save_model(out, m)
    return videos, clips, str(out)


def decode_reference(videos: str, clips: str, n_background: int = 20, model: str | None = None) -> dict:
    """Child side: the references of a colour run, timed on the same videos, one thread (``time.thread_time``):
    decoding alone (every camera; FFmpeg held to the calling thread as in the pipeline's readers,
    :data:`silpose.app.recordings.sources.DECODER_PARAMS`, so that the figure holds all of the decoding's CPU --
    with FFmpeg's own threads a thread's clock misses theirs), and OpenCV's MOG2 (shadow detection, learnt on the
    empty-room clips, learning rate 0) on every decoded full-size frame; with ``model`` (its rig sets each camera's
    working size, :mod:`silpose.app.recordings.resolution`) also the pipeline's own per-frame stages there:
    shrinking the frame to the working size (``shrink``) and segmenting it with the pipeline's
    :class:`~silpose.segment.BackgroundModel` learnt from the shrunk clips (``segment``). CPU ms per time step."""
    import time

    import cv2
    import numpy as np

    from silpose.app.recordings.resolution import shrink, work_size
    from silpose.app.recordings.silhouettes import SEGMENT_DEFAULTS
    from silpose.app.recordings.sources import DECODER_PARAMS
    from silpose.segment import BackgroundModel

    cv2.setNumThreads(1)
    warm_compiled()  # the segmentation's compiled pass: numba's import is not a frame's work
    rig = None
    if model:
        from silpose.model.persistence import load_model  # scikit-learn: seconds to import on a loaded machine

        rig = load_model(model).rig_
    decode = mog = resize = seg = 0.0
    steps = 0
    for video in sorted(Path(videos).glob("*.mp4")):
        size = None
        if rig is not None:
            cam = rig[list(rig.names).index(video.stem)]
            size = work_size(cam, rig.workspace.center)
        sub = cv2.createBackgroundSubtractorMOG2(history=n_background, varThreshold=16, detectShadows=True)
        cap = cv2.VideoCapture(str(Path(clips) / video.name), cv2.CAP_FFMPEG, DECODER_PARAMS)
        small = []
        while True:
            ok, img = cap.read()
            if not ok:
                break
            sub.apply(img)
            if size is not None:
                small.append(shrink(img, size))
        cap.release()
        bg = BackgroundModel(**SEGMENT_DEFAULTS).fit(np.stack(small)) if small else None
        cap = cv2.VideoCapture(str(video), cv2.CAP_FFMPEG, DECODER_PARAMS)
        n = 0
        while True:
            t0 = time.thread_time()
            ok, img = cap.read()
            decode += time.thread_time() - t0
            if not ok:
                break
            t0 = time.thread_time()
            sub.apply(img, learningRate=0)
            mog += time.thread_time() - t0
            if bg is not None:
                t0 = time.thread_time()
                frame = shrink(img, size)
                t1 = time.thread_time()
                bg.segment(frame)
                resize += t1 - t0
                seg += time.thread_time() - t1
            n += 1
        cap.release()
        steps = max(steps, n)
    out = {"steps": steps, "decode_cpu_ms_per_step": 1000 * decode / steps, "mog2_cpu_ms_per_step": 1000 * mog / steps}
    if rig is not None:
        out.update(shrink_cpu_ms_per_step=1000 * resize / steps, segment_cpu_ms_per_step=1000 * seg / steps)
    return out


def warm_compiled() -> None:
    """Import numba's compiled loops and load them from numba's cache, as a run does once per process (~1 s: numba's
    import), so that a run's clock holds only its own work, like the other once-per-process imports."""
    import numpy as np

    from silpose.app.recordings.outline_kernels import nearest_on_outline
    from silpose.model.robust import kernels
    from silpose.model.untangle import untangle_orders
    from silpose.segment import colour_kernels
    from silpose.segment.ncc import background_window_stats, shadow_mask
    from silpose.shared.contours import single_blob_contour

    square = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]])
    nearest_on_outline(np.zeros((1, 2)), square, np.zeros(1, np.int64), np.full(1, -1, np.int64), 1, np.ones(1))
    kernels.nearest_shifts(square.copy(), square.copy(), 1)
    kernels.near_any_edge(square.copy(), square.copy(), np.ones(1), np.zeros(1, np.int64), np.zeros(1, np.int64), 1)
    kernels.biweight_pseudo(square[None].copy(), square[None].copy(), np.ones((1, 1), bool), 3.0, 0.3)
    single_blob_contour(np.ones((2, 2), np.uint8), 4)
    untangle_orders(square)
    colour_kernels.normalise_and_score(np.zeros((1, 3), np.uint8), np.ones(3, np.float32), np.zeros((1, 3), np.float32),
                                       np.ones((1, 3), np.float32), np.float32(1), np.empty((1, 3), np.uint8),
                                       np.empty((1, 1), np.float32), np.empty((1, 1), np.float32), np.empty((1, 1), bool))
    for noise in (None, np.ones((9, 9))):  # the shadow test's compiled window sums, with and without noise correction
        support = np.ones((9, 9), bool)
        shadow_mask(np.zeros((9, 9), np.uint8), background_window_stats(np.ones((9, 9)), 3, 1.0, noise), support,
                    0.25, 0.9, (0.25, 1.0), at=support)


def cpu_seconds() -> float:
    """CPU seconds of this process and of its children that ended (the overlay videos' worker processes,
    :mod:`silpose.app.recordings.overlay_video`)."""
    import os

    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def measure(model: str, videos: str, out: str, overlays: bool, threads: int | None, robust: bool | None = None,
            background: str | None = None, work_person_px: int | None = None, carve: bool | None = None,
            silhouette_fit: bool = True, reader_threads: bool | None = None) -> dict:
    """Child side: one run of the pipeline; returns its figures (module docstring, ``run`` rows)."""
    import time

    import psutil

    from silpose.app.recordings.pipeline import RecordingOptions, run_recording
    from silpose.model.persistence import load_model
    from silpose.shared.memory import peak_rss_bytes

    m = load_model(model)
    # the imports a run makes once per process, before the baseline and the clock: the floor plan's (pyplot, its
    # Agg backend, PIL's image plugins) and pyarrow's pandas metadata (the Parquet writer's close); ~0.3 s of a
    # run's finish on a loaded 2-core machine where Python compiles them (PYTHONDONTWRITEBYTECODE)
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.pyplot  # noqa: F401
    import pyarrow.pandas_compat  # noqa: F401
    from PIL import Image

    Image.preinit()
    warm_compiled()

    baseline = psutil.Process().memory_info().rss
    cpu0, t0 = cpu_seconds(), time.perf_counter()
    extra = {} if work_person_px is None else {"work_person_px": work_person_px}
    s = run_recording(m, videos, out, RecordingOptions(masks=background is None, background=background, overlays=overlays,
                                                       threads=threads, robust=robust, carve=carve,
                                                       silhouette_fit=silhouette_fit, reader_threads=reader_threads,
                                                       **extra))
    cpu, wall = cpu_seconds() - cpu0, time.perf_counter() - t0
    peak = peak_rss_bytes()
    mb = 2.0**-20
    stages = {k: v for k, v in s.timings.items() if k not in ("total", "setup", "finish")}
    busy = sum(stages.values()) or 1.0
    return {"steps": s.n_steps, "persons": s.n_persons, "wall_s": wall, "steps_per_s": s.n_steps / wall,
            "steady_steps_per_s": s.steady_steps_per_second, "setup_s": s.timings.get("setup", float("nan")),
            "finish_s": s.timings.get("finish", float("nan")),
            "cpu_ms_per_step": 1000 * cpu / s.n_steps, "steps_per_cpu_s": s.n_steps / cpu,
            **{f"share_{k}": v / busy for k, v in stages.items()},
            "baseline_mb": baseline * mb, "peak_mb": peak * mb, "run_mb": (peak - baseline) * mb}


def foot_points(masks, rig, min_area: int, cluster_m: float = 0.5):
    """People on the floor from foot points (the alternative to the occupancy grid): every usable blob not
    touching the border gives the floor point under its lowest row at its centroid's column (the pixel's
    ray met with z = 0, i.e. the camera's floor homography); points of different cameras within
    ``cluster_m`` are one person (greedy, strongest cluster first), kept when two cameras or more agree.
    Returns (D, 2) metres."""
    import numpy as np

    from silpose.app.recordings.blobs import find_blobs

    pts, cams = [], []
    for k, (cam, m) in enumerate(zip(rig, masks)):
        b = find_blobs(m, min_area)
        for lab in np.flatnonzero(b.usable & ~b.touches_border):
            x, y, w, h = b.bbox[lab]
            u = np.array([b.centroid[lab, 0], y + h - 1, 1.0])
            d = cam.R.T @ np.linalg.solve(cam.K, u)
            c = cam.center
            if d[2] >= 0:
                continue
            pts.append((c - c[2] / d[2] * d)[:2])
            cams.append(k)
    pts, cams = np.array(pts).reshape(-1, 2), np.array(cams)
    left = np.ones(len(pts), bool)
    out = []
    while left.any():
        idx = np.flatnonzero(left)
        near = np.linalg.norm(pts[idx, None] - pts[None, idx], axis=2) <= cluster_m
        best = int(np.argmax(near.sum(axis=1)))
        members = idx[near[best]]
        # one point per camera: the nearest to the seed
        chosen = {}
        for i in members:
            if cams[i] not in chosen or np.linalg.norm(pts[i] - pts[idx[best]]) < np.linalg.norm(pts[chosen[cams[i]]] - pts[idx[best]]):
                chosen[cams[i]] = i
        sel = np.array(list(chosen.values()))
        if len(sel) >= 2:
            out.append(pts[sel].mean(axis=0))
        left[sel if len(sel) >= 2 else idx[best:best + 1]] = False
    return np.array(out).reshape(-1, 2)


def _floor_rows(lab: Path, rig) -> list[dict]:
    """The two floor methods on every frame of the recording (decoded and binarised once)."""
    import time

    import cv2
    import numpy as np
    from scipy.optimize import linear_sum_assignment

    from silpose.app.recordings.floor import FloorGrid
    from silpose.app.recordings.resolution import min_blob_area
    from silpose.app.recordings.silhouettes import binarise
    from silpose.shared.rig_frame import DEFAULT_WORKSPACE

    truth = np.load(lab / "truth.npz")["joints"][:, :, 0, :2]
    masks = []
    for cam in rig:
        cap = cv2.VideoCapture(str(lab / "masks" / f"{cam.name}.mp4"))
        frames = []
        while True:
            ok, img = cap.read()
            if not ok:
                break
            frames.append(binarise(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)))
        masks.append(frames)
    grid = FloorGrid(list(rig), DEFAULT_WORKSPACE.bounds)
    methods = {"occupancy grid": lambda ms: grid.locate(ms).positions,
               "foot points": lambda ms: foot_points(ms, rig, min_blob_area(rig[0], rig[0], DEFAULT_WORKSPACE.center))}
    rows = []
    for name, fn in methods.items():
        found = false = 0
        errs, seconds = [], 0.0
        for f in range(len(truth)):
            t0 = time.perf_counter()
            det = fn([masks[k][f] for k in range(len(rig))])
            seconds += time.perf_counter() - t0
            cost = np.linalg.norm(det[:, None] - truth[f][None], axis=2) if len(det) else np.zeros((0, len(truth[f])))
            r, c = linear_sum_assignment(cost) if len(det) else ([], [])
            ok = [i for i, j in zip(r, c) if cost[i, j] <= 0.5]
            found += len(ok)
            false += len(det) - len(ok)
            errs += [cost[i, j] for i, j in zip(r, c) if cost[i, j] <= 0.5]
        total = truth.shape[0] * truth.shape[1]
        rows.append({"name": "floor", "method": name, "person_frames": total, "recall": found / total,
                     "false_detections": false, "error_cm": 100 * float(np.mean(errs)) if errs else float("nan"),
                     "error_max_cm": 100 * float(np.max(errs)) if errs else float("nan"),
                     "ms_per_frame": 1000 * seconds / len(truth)})
    return rows


def _overlay_shares(rows: list[dict]) -> None:
    """On each ``... with overlays`` run row, the overlays' share of the run measured against the same run
    without them (same process, same input): ``overlay_share_wall`` = 1 - wall(without) / wall(with), and
    ``overlay_share_cpu`` the same with CPU seconds, the worker processes' included (the overlays are drawn and
    encoded beside the run's thread, so the stage timings' ``share_overlays`` -- the run's thread queueing frames --
    understates them)."""
    runs = {r["run"]: r for r in rows if r.get("name") == "run"}
    for label, r in runs.items():
        plain = runs.get(label.replace(" with overlays", "")) if label.endswith(" with overlays") else None
        if plain is None:
            continue
        r["overlay_share_wall"] = 1.0 - plain["wall_s"] / r["wall_s"] * r["steps"] / plain["steps"]
        r["overlay_share_cpu"] = 1.0 - plain["cpu_ms_per_step"] / r["cpu_ms_per_step"]


def run(n_frames: int = 150, repeat: int = 10, train: int = 400, n_points: int = 200, model: str | None = None,
        threads: int | None = None, colour_scale: int = 3, colour_frames: int = 60, colour_1080p: bool = True,
        runs: list | None = None) -> list[dict]:
    """Make the inputs, measure (module docstring). ``model``: a model file of the lab rig (None: train one on
    ``train`` walkers, the full-size hyperparameters when ``train`` >= 400, else tiny ones). ``colour_1080p``: also
    a colour run at 1920x1080 (the issue's full HD), without overlays. ``runs``: the labels of the runs to make
    (None: all; ``"colour"`` is the colour runs and their references)."""
    import numpy as np

    from silpose.datagen.lab import make_lab_recording, unpack_masks
    from benchmarks.recording_scores import (clean_reference, joints_inside, read_rows, read_view_status, score_reference,
                                             score_rows)
    from silpose.model.persistence import load_model

    with tempfile.TemporaryDirectory(prefix="silpose-bench-recordings-") as tmp:
        tmp = Path(tmp)
        lab = make_lab_recording(tmp / "lab", n_frames=n_frames)
        if model is None:
            (tmp / "train").mkdir()
            model = str(_train(tmp / "train", train, n_points, MODEL if train >= 400 else TINY_MODEL))
        wanted = (lambda label: runs is None or label in runs)
        long_frames = _ping_pong(lab / "masks", tmp / "long", repeat) if wanted(f"{repeat}x") else 0
        rows = []
        plan = [("1x", lab / "masks", False, threads, None, {}), (f"{repeat}x", tmp / "long", False, threads, None, {}),
                (f"{repeat}x, --robust", tmp / "long", False, threads, True, {}),
                ("1x single-threaded", lab / "masks", False, 0, None, {"reader_threads": False}),
                ("1x with overlays", lab / "masks", True, threads, None, {}),
                (f"{repeat}x with overlays", tmp / "long", True, threads, None, {}),
                ("1x carved", lab / "masks", False, threads, None, {"carve": True}),
                ("1x without the silhouette fit", lab / "masks", False, threads, None, {"silhouette_fit": False})]
        if wanted("colour"):
            big = (colour_scale * 644, colour_scale * 486)
            videos, clips, big_model = _colour_recording(lab, tmp / "big", big, model, colour_frames)
            size = f"{big[0]}x{big[1]}"
            plan += [(f"colour 4 x {size}", videos, False, threads, None, {"background": str(clips), "model": big_model}),
                     (f"colour 4 x {size} with overlays", videos, True, threads, None,
                      {"background": str(clips), "model": big_model})]
            if colour_1080p:
                hd_videos, hd_clips, hd_model = _colour_recording(lab, tmp / "hd", (1920, 1080), model, colour_frames)
                plan.append(("colour 4 x 1920x1080", hd_videos, False, threads, None,
                             {"background": str(hd_clips), "model": hd_model}))
            ref = subproc.call(__name__, "decode_reference", dict(videos=str(videos), clips=str(clips), model=big_model))
            if ref.error:
                raise RuntimeError(f"recordings: decode reference failed ({ref.error})")
            rows.append({"name": "reference", "run": f"colour 4 x {size}: decode / MOG2 / shrink + segment alone, 1 thread",
                         **ref.value})
        first = carved = unfitted = None
        for label, videos, overlays, thr, robust, extra in plan:
            if not (wanted(label) or (label.startswith("colour") and wanted("colour"))):
                continue
            out = tmp / f"out-{len(rows)}"
            res = subproc.call(__name__, "measure", dict(model=extra.get("model", model), videos=str(videos), out=str(out),
                                                          overlays=overlays, threads=thr, robust=robust,
                                                          background=extra.get("background"),
                                                          carve=extra.get("carve"),
                                                          silhouette_fit=extra.get("silhouette_fit", True),
                                                          reader_threads=extra.get("reader_threads")))
            if res.error:
                raise RuntimeError(f"recordings: run {label} failed ({res.error})")
            rows.append({"name": "run", "run": label, **res.value})
            if label == "1x":
                first = out
            if label == "1x carved":
                carved = out
            if label == "1x without the silhouette fit":
                unfitted = out
        _overlay_shares(rows)
        runs_by = {r["run"]: r for r in rows if r.get("name") == "run"}
        if "1x" in runs_by and "1x carved" in runs_by:
            c, one = runs_by["1x carved"], runs_by["1x"]
            c["steps_vs_1x"] = c["steps_per_s"] / one["steps_per_s"]
            c["cpu_vs_1x"] = c["cpu_ms_per_step"] / one["cpu_ms_per_step"]
        if wanted(f"{repeat}x") and wanted("1x"):
            big = next(r for r in rows if r["run"] == f"{repeat}x")
            one = next(r for r in rows if r["run"] == "1x")
            big["peak_mb_vs_1x"] = big["peak_mb"] / one["peak_mb"]
            big["steps_vs_1x"] = big["steps"] / one["steps"]
            assert big["steps"] == long_frames
        if first is None:
            return rows
        truth = np.load(lab / "truth.npz")
        ref = score_reference(clean_reference(load_model(model), unpack_masks(truth)), truth["joints"])
        cameras = list(load_model(model).rig_)
        for label, folder in (("recording (lossy mask videos)", first), ("recording, carved", carved),
                              ("recording, without the silhouette fit", unfitted)):
            if folder is None:
                continue
            got = read_rows(folder / "joints.parquet")
            sc = score_rows(got, truth["joints"])
            inside = joints_inside(got, read_view_status(folder / "joints.parquet"), sc["per_row"]["paired"],
                                   unpack_masks(truth), cameras)
            rows.append({"name": "accuracy", "input": label, "frames": n_frames,
                         "persons": sc["persons"], "identity_switches": sc["identity_switches"],
                         "person_frames": sc["person_frames"], "paired": sc["paired"], "with_joints": sc["with_joints"],
                         "false_rows": sc["false_rows"],
                         **{f"views_ge_{k}": v for k, v in sc["views_at_least"].items()},
                         "root_cm": sc["root_error_cm"], "world_cm": sc["world_error_cm"],
                         "relative_cm": sc["relative_error_cm"], "joints_inside": inside["share"]})
        rows.append({"name": "accuracy", "input": "clean per-person masks, every view", "frames": n_frames,
                     "with_joints": ref["with_joints"], "root_cm": ref["root_error_cm"], "world_cm": ref["world_error_cm"],
                     "relative_cm": ref["relative_error_cm"]})
        rows += _floor_rows(lab, load_model(model).rig_)
    return rows
