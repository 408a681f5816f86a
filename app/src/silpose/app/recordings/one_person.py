"""One person (``silpose infer --people 1``; ``--frames DIR`` is a frames folder with ``--people 1``).

The recording's cameras are read, synchronised and segmented as for several people (:mod:`.sources`,
:mod:`.frames_source`, :mod:`.silhouettes`, at the working resolution of :mod:`.resolution`); what one person
changes is who owns a blob: nobody else can, so there is no floor grid, no tracking and no view assignment. Per
camera and time step the view is the mask's largest blob (:mod:`.blobs`) when it has at least the minimum blob
area (:func:`~.resolution.min_blob_area`), its outer contour traced at the model's ``n_points`` and scaled to the
rig camera's pixels; otherwise a missing view with its status (docs/conventions.md, "View statuses"):
``empty mask`` (no foreground), ``too small`` (the largest blob is under the minimum area), ``no video`` (no
video or frame folder for the camera), ``video ended``, ``not modelled`` (a camera the model was not trained on).
A largest blob touching the image border is used, as ``silpose infer --frames`` always did (several people mark
such a view ``border``: there a cut outline may be anyone's; here it is the person's, if partly).

Colour frames are segmented with the background model's own defaults (:data:`ONE_PERSON_SEGMENT`: the largest
blob kept, no per-frame gain), the segmentation ``silpose infer --frames`` has always used; the caller's
``segment_params`` override them.

Inference runs per chunk of time steps (:func:`silpose.app.inference.infer_rows`: robust inference, the top-3
hypotheses (8 with ``temporal``), untangled contours; a step without a usable view gets NaN joints); at the end,
with ``temporal``, each step's answer is the hypothesis chosen along the whole sequence (one track, the Viterbi path:
:func:`silpose.app.inference.apply_temporal`). The answer is then put in the room (:func:`place_in_room`): the
views alone place its root, there being no floor grid (:func:`.placement.place_without_floor`), and with
``opt.silhouette_fit`` each joint moves inside the person's outline in every view used (:mod:`.silhouette_fit`), as
for several people. The joints file holds the root-relative joints of that placed answer and the root, in silpose's
frame, and the joints in the calibration's frame and units; the overlays draw the same skeleton.

:func:`run_one_person` is the library entry (evaluation and benchmarks hook into its chunks);
:func:`run_one_person_inference` is the command: the joints file, ``<out stem>.segmentation.json``,
``<out stem>.contours.npz`` and the overlays (:mod:`.overlay_png`) in ``<out stem>.overlays/``.
"""

from __future__ import annotations

import dataclasses
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from silpose.model.hypotheses import single_answer
from silpose.model.persistence import load_model

from ..errors import RecordingError
from ..inference import (InferOptions, apply_temporal, frame_status, hypotheses_kept, infer_rows, merge_results,
                         status_warnings)
from ..view_status import VIEW_EMPTY, VIEW_ENDED, VIEW_NO_VIDEO, VIEW_NOT_MODELLED, VIEW_OK, VIEW_TOO_SMALL
from ..writers import sibling, write_contours, write_joints, write_segmentation
from .blobs import Blobs, blob_contour, find_blobs
from .frames_source import bad_frame, frames_folder_run
from .overlay_png import draws_overlays, overlay_sink
from .pipeline import RecordingOptions, check_background_options, make_silhouettes
from .placement import place_without_floor
from .silhouette_fit import fit_to_silhouettes, share_inside
from .resolution import min_blob_area, to_rig_px, to_work_px, work_camera, work_size
from .silhouettes import at_size
from .sources import CameraReader, open_recording, parse_offsets

#: BackgroundModel arguments for one person (module docstring); ``RecordingOptions.segment_params`` override them
ONE_PERSON_SEGMENT = {"largest_blob": True, "gain": False}
#: the stages timed (seconds, summed over cameras)
STAGES = ("background", "read", "segment", "contours", "infer", "place", "overlays")


def largest_view(blobs: Blobs, n_points: int) -> tuple[np.ndarray | None, str, int]:
    """(contour (n_points, 2) px of the largest usable blob or None, status, that blob's area px): the view of one
    person (module docstring); ``too small`` when the mask has foreground but no usable blob."""
    if blobs.empty:
        return None, VIEW_EMPTY, 0
    area = np.where(blobs.usable, blobs.area, -1)
    label = int(np.argmax(area))
    if area[label] < 0:
        return None, VIEW_TOO_SMALL, int(blobs.area[1:].max())
    pts = blob_contour(blobs, label, n_points)
    return (None, VIEW_EMPTY, 0) if pts is None else (pts, VIEW_OK, int(blobs.area[label]))


@dataclass
class OnePersonChunk:
    """One chunk of n time steps, handed to ``on_chunk``: start (first step), names (n,) frame names, masks
    {camera: (n, h, w) bool} at the working resolution (read cameras), contours (n, K, n_pts, 2) rig px (NaN where
    missing), present (n, K), status (n, K) str, result: the chunk's InferenceResult."""

    start: int
    names: list
    masks: dict
    contours: np.ndarray
    present: np.ndarray
    status: np.ndarray
    result: object


@dataclass
class OnePersonResult:
    """A whole run, N time steps, K rig cameras: frames (N,) str; cameras (K,); contours (N, K, n, 2) rig px;
    present (N, K); status (N, K) str; area (N, K) px of the used (or too small) blob in the rig camera's pixels;
    min_area {camera: px at the working resolution}; result: InferenceResult over the modelled views (temporal
    choice applied); joints_world (N, 19, 3) metres, silpose's frame: the answer placed in the room
    (:func:`place_in_room`; NaN without a usable view); timings: seconds per stage (:data:`STAGES`); warnings."""

    frames: np.ndarray
    cameras: tuple
    contours: np.ndarray
    present: np.ndarray
    status: np.ndarray
    area: np.ndarray
    min_area: dict
    result: object
    joints_world: np.ndarray
    timings: dict
    warnings: list[str] = field(default_factory=list)
    overlays: list[Path] = field(default_factory=list)


def run_one_person(model, source, opt: RecordingOptions | None = None, *, frames_layout: bool = False,
                   temporal: bool = True, overlay_dir: Path | None = None,
                   on_chunk: Callable[[OnePersonChunk], None] | None = None,
                   progress: Callable[[int, int], None] | None = None,
                   warn: Callable[[str], None] | None = None) -> OnePersonResult:
    """Joints of one person from every camera of ``source`` (module docstring).

    Args:
        model: a fitted ShapeStructureModel with a rig, or a model file's path.
        source: a recording folder or a frames folder (:mod:`.frames_source`; ``frames_layout`` requires one).
        opt: :class:`~.pipeline.RecordingOptions` (masks / background / offsets / min_area / robust / chunk /
            threads / segment_params / work_person_px / max_steps / hypotheses / overlays are used).
        temporal: choose each step's answer along the sequence (else each step's most probable hypothesis).
        overlay_dir: where ``opt.overlays`` go (required when it asks for them).
        on_chunk: called with each :class:`OnePersonChunk` after its inference. progress: (steps done, total or -1).
        warn: called with each warning line as it is found.
    """
    opt = opt or RecordingOptions(overlays=False)
    if isinstance(model, (str, Path)):
        model = load_model(Path(model))
    rig = getattr(model, "rig_", None)
    if rig is None:
        raise RecordingError("the model file stores no rig, so camera folders cannot be matched to views")
    timings = dict.fromkeys(STAGES, 0.0)
    videos, opt, frame_names = frames_folder_run(source, opt, rig, require=frames_layout)
    check_background_options(opt, videos, rig)
    opt = dataclasses.replace(opt, segment_params={**ONE_PERSON_SEGMENT, **(opt.segment_params or {})})
    names = list(rig.names)
    lay = model.fitted_layout()
    modelled, n_pts, K = [names[v] for v in lay.views], lay.n_points, len(names)
    recording = open_recording(videos, rig, parse_offsets(opt.offsets, names))
    warnings: list[str] = []

    def note(line: str) -> None:
        warnings.append(line)
        if warn:
            warn(line)

    for w in recording.warnings:
        note(w)
    work = [work_camera(c, work_size(c, rig.workspace.center, opt.work_person_px)) for c in rig]
    used = [c for c in recording.sources if c in modelled]
    if not used:
        raise RecordingError(f"{videos}: no camera the model uses ({', '.join(modelled)}) has a video or frames")
    idx = {c: names.index(c) for c in names}
    sources = {c: at_size(recording.sources[c], (work[idx[c]].width, work[idx[c]].height)) for c in used}
    t0 = time.perf_counter()
    silhouettes, start = make_silhouettes(opt, rig, sources, work)
    timings["background"] = time.perf_counter() - t0
    if frame_names is not None:  # the frames a background was learnt from (--background-frames) are not steps
        frame_names = frame_names[start:]
    total = recording.n_steps - start if recording.n_steps >= 0 else -1
    if opt.max_steps is not None:
        total = opt.max_steps if total < 0 else min(total, opt.max_steps)
    first_frame = start - min([0] + list(recording.offsets.values()))
    min_area = {c: min_blob_area(rig[idx[c]], work[idx[c]], rig.workspace.center, opt.min_area) for c in used}
    base = np.array([VIEW_NOT_MODELLED if c in recording.sources and c not in modelled else VIEW_NO_VIDEO
                     for c in names], dtype=object)
    readers = {c: CameraReader(sources[c], silhouettes.grey, start) for c in used}
    per_cam = {c: dict.fromkeys(("read", "segment", "contours"), 0.0) for c in used}
    keep = on_chunk is not None or draws_overlays(opt.overlays)

    def look(c: str):
        """One camera's next step (in a worker thread): (image, mask, (contour, status, area)) or None at the end."""
        t = per_cam[c]
        t0 = time.perf_counter()
        img = readers[c].read()
        t1 = time.perf_counter()
        t["read"] += t1 - t0
        if img is None:
            return None
        mask = silhouettes(c, img)
        t2 = time.perf_counter()
        pts, status, area = largest_view(find_blobs(mask, min_area[c]), n_pts)
        t["segment"] += t2 - t1
        t["contours"] += time.perf_counter() - t2
        return img, mask, (pts, status, area)

    threads = min(len(used), os.cpu_count() or 1) if opt.threads is None else int(opt.threads)
    pool = ThreadPoolExecutor(max_workers=threads) if threads > 0 else None
    mapper = pool.map if pool else map
    robust = (not opt.masks) if opt.robust is None else bool(opt.robust)
    options = InferOptions(noise_variance=opt.noise_variance, hypotheses=hypotheses_kept(opt.hypotheses, temporal),
                           robust=robust, untangle=True)
    overlays = None
    if draws_overlays(opt.overlays):
        if overlay_dir is None:
            raise RecordingError("overlays need a folder (overlay_dir)")
        overlays = overlay_sink(opt.overlays, Path(overlay_dir), names, {c.name: (c.width, c.height) for c in work},
                                recording.fps, first_frame, frame_names)
    contours, present, status, area, parts, order = [], [], [], [], [], []
    ended: set[str] = set()
    step = 0
    try:
        done = False
        while not done:
            n0 = step
            c_chunk, p_chunk, s_chunk, a_chunk = [], [], [], []
            frames_kept: list[dict] = []
            while step - n0 < opt.chunk:
                if total >= 0 and step >= total:
                    done = True
                    break
                seen = dict(zip(used, mapper(look, used)))
                gone = [c for c, v in seen.items() if v is None and c not in ended]
                if gone and frame_names is not None and step < len(frame_names):  # the layout's contract
                    raise bad_frame(sources[gone[0]], start + step)
                if gone:
                    ended.update(gone)
                    if len(ended) == len(used):
                        done = True
                        break
                    note(f"{', '.join(recording.sources[c].path.name for c in gone)} ended after {step} frames: a "
                         "missing view ('video ended') from there on, the other cameras go on")
                c_row = np.full((K, n_pts, 2), np.nan)
                s_row, a_row = base.copy(), np.zeros(K, np.int64)
                for c, v in seen.items():
                    k = idx[c]
                    if v is None:
                        s_row[k] = VIEW_ENDED
                        continue
                    pts, s_row[k], a = v[2]
                    scale = rig[k].width * rig[k].height / (work[k].width * work[k].height)
                    a_row[k] = int(round(a * scale))
                    if pts is not None:
                        c_row[k] = to_rig_px(pts, rig[k], work[k])
                c_chunk.append(c_row)
                s_chunk.append(s_row)
                a_chunk.append(a_row)
                p_chunk.append(s_row == VIEW_OK)
                if keep:
                    frames_kept.append({c: v for c, v in seen.items() if v is not None})
                step += 1
                if progress:
                    progress(step, total)
            if step == n0:
                break
            cs, ps = np.stack(c_chunk), np.stack(p_chunk)
            t0 = time.perf_counter()
            res = infer_rows(model, cs, ps, options=options)
            timings["infer"] += time.perf_counter() - t0
            parts.append(res)
            order.append(np.arange(n0, step))
            contours.append(cs)
            present.append(ps)
            status.append(np.stack(s_chunk))
            area.append(np.stack(a_chunk))
            if overlays is not None:
                t0 = time.perf_counter()
                _draw(overlays, rig, work, names, modelled, n0 + first_frame, frames_kept, status[-1], res,
                      silhouettes.grey, cs, ps, opt.silhouette_fit)
                timings["overlays"] += time.perf_counter() - t0
            if on_chunk is not None:
                chunk_names = [_frame_name(frame_names, first_frame, i) for i in range(n0, step)]
                masks = {c: np.stack([f[c][1].astype(bool) if c in f else np.zeros(f_shape(work[idx[c]]), bool)
                                      for f in frames_kept]) for c in used}
                on_chunk(OnePersonChunk(n0, chunk_names, masks, cs, ps, status[-1], res))
        files = overlays.close() if overlays is not None else []
        overlays = None
    except BaseException:
        if overlays is not None:
            overlays.abort()
        raise
    finally:
        if pool:
            pool.shutdown()
        for r in readers.values():
            r.close()
    for r in readers.values():
        line = r.summary()
        if line and frame_names is None:
            note(line)
    if step == 0:
        raise RecordingError(f"{videos}: no frames to read")
    for t in per_cam.values():
        for k, v in t.items():
            timings[k] += v
    result = merge_results(parts, order, step)
    if temporal:
        apply_temporal(result)
    frames = np.array([_frame_name(frame_names, first_frame, i) for i in range(step)])
    all_contours, all_present = np.concatenate(contours), np.concatenate(present)
    t0 = time.perf_counter()
    world = place_in_room(single_answer(result.joints, result.hypotheses), result, rig, all_contours, all_present,
                          opt.silhouette_fit)
    timings["place"] = time.perf_counter() - t0
    return OnePersonResult(frames, tuple(names), all_contours, all_present, np.concatenate(status),
                           np.concatenate(area), min_area, result, world, timings, warnings, files)


def place_in_room(pose: np.ndarray, result, rig, contours: np.ndarray, present: np.ndarray, fit: bool) -> np.ndarray:
    """(N, 19, 3) metres, silpose's frame: one person's answer put in the room (module docstring).

    Args:
        pose: (N, 19, 3) root-relative joints, metres (the single answer of ``result``).
        result: the InferenceResult (``centroid``, ``views_present``, ``views``: modelled views; ``joint_std``).
        rig: the rig; contours: (N, K, n, 2) rig px, every rig camera's observed outline; present: (N, K) bool,
            the views used.
        fit: move the joints inside the outlines (:func:`.silhouette_fit.fit_to_silhouettes`).
    Returns:
        the placed joints; NaN for rows without a used view or a finite answer.
    """
    pose = np.asarray(pose, float)
    world = np.full(pose.shape, np.nan)
    ok = np.flatnonzero(result.views_present.any(axis=1) & np.isfinite(pose).all(axis=(1, 2)))
    if len(ok) == 0:
        return world
    cams = [rig[v] for v in result.views]
    roots = place_without_floor(pose[ok], result.centroid[ok], result.views_present[ok], cams,
                                np.asarray(rig.workspace.center, float)[:2])
    world[ok] = pose[ok] + roots[:, None]
    if fit:
        world[ok] = fit_to_silhouettes(world[ok], result.joint_std[ok], contours[ok], present[ok], list(rig))
    return world


def f_shape(cam) -> tuple[int, int]:
    """(height, width) of a camera's frames."""
    return cam.height, cam.width


def _frame_name(frame_names, first_frame: int, i: int) -> str:
    return str(frame_names[i]) if frame_names is not None else f"{first_frame + i:05d}"


def _draw(overlays, rig, work, names, modelled, frame0: int, frames_kept: list[dict], status: np.ndarray, res,
          grey: bool, contours: np.ndarray, present: np.ndarray, fit: bool) -> None:
    """Overlay frames of one chunk (:func:`.overlay_video.draw_frame`): the person's blob outline, the reconstructed
    contours of the used views and the skeleton of the chunk's answers placed in the room (:func:`place_in_room`;
    the written joints are chosen along the whole sequence, so a frame's may differ)."""
    placed = place_in_room(single_answer(res.joints, res.hypotheses), res, rig, contours, present, fit)
    for i, seen in enumerate(frames_kept):
        world = placed[i]
        for k, c in enumerate(names):
            cam, wcam = rig[k], work[k]
            v = seen.get(c)
            outline = v[2][0] if v is not None else None
            recon = to_work_px(res.contours_px[i, modelled.index(c)], cam, wcam) if c in modelled else None
            jp = wcam.project(world) if np.all(np.isfinite(world)) else None
            item = {"person": 1, "status": status[i, k], "outline": outline, "recon": recon, "joints_px": jp,
                    "anchor_px": None}
            picture = None if v is None else (v[1] if grey else v[0])
            overlays.draw(c, picture, (wcam.width, wcam.height), frame0 + i, [item])  # drawn beside the run


def run_one_person_inference(model_path: Path, source: Path, *, out: Path, opt: RecordingOptions,
                             frames_layout: bool = False, temporal: bool = True, save_contours: bool = False,
                             overlay_dir: Path | None = None, progress: Callable[[int, int], None] | None = None,
                             warn: Callable[[str], None] | None = None) -> str:
    """Everything ``silpose infer MODEL --people 1`` (or ``--frames DIR``) does; returns a summary (several lines,
    ``warning:`` lines last; the warnings found while reading went to ``warn``)."""
    model_path, source, out = Path(model_path), Path(source), Path(out)
    if out.suffix.lower() not in (".parquet", ".json"):
        raise RecordingError(f"{out}: the joints file must end in .parquet or .json")
    model = load_model(model_path)
    if draws_overlays(opt.overlays) and overlay_dir is None:
        overlay_dir = sibling(out, ".overlays")
    fr = run_one_person(model, source, opt, frames_layout=frames_layout, temporal=temporal, overlay_dir=overlay_dir,
                        progress=progress, warn=warn)
    rig_names = list(model.rig_.names)
    status = frame_status(fr.result)
    inside = share_inside(fr.joints_world, fr.contours, fr.present, list(model.rig_))
    write_joints(out, fr.frames, fr.result, rig_names, None, str(model_path), status=status, world=fr.joints_world,
                 transform=model.rig_.transform, inside=inside)
    seg_path = sibling(out, ".segmentation.json")
    areas = sorted(set(fr.min_area.values()))
    write_segmentation(seg_path, fr, source, "/".join(str(a) for a in areas) + " px at the working resolution")
    lines = [f"{out}: joints of {len(fr.frames)} frames from {source}",
             f"{seg_path}: the status of every view (frame and camera)"]
    if save_contours:
        cpath = sibling(out, ".contours.npz")
        write_contours(cpath, fr.frames, fr.result, rig_names)
        lines.append(f"{cpath}: reconstructed contours")
    if fr.overlays:
        lines.append(f"{overlay_dir}/: overlays")
    views = list(model.layout_.views)
    st = fr.status[:, views]
    none = int((~fr.present[:, views].any(axis=1)).sum())
    counts = {s: int((st == s).sum()) for s in dict.fromkeys(st.ravel().tolist()) if s != VIEW_OK}
    lines.append(f"views used {int((st == VIEW_OK).sum())} of {st.size}"
                 + "".join(f", {n} {s}" for s, n in counts.items())
                 + (f"; {none} frame(s) had no usable view (NaN joints)" if none else ""))
    if np.isfinite(inside).any():
        lines.append(f"joints inside the person's outline in the views used: {np.nanmean(inside):.3f} (column inside)")
    lines.append("seconds: " + ", ".join(f"{k} {v:.2f}" for k, v in fr.timings.items()))
    lines += status_warnings(fr.frames, status, getattr(model, "plausibility_", None) is not None)
    return "\n".join(lines)
