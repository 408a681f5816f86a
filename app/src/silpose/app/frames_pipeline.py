"""``silpose infer MODEL --frames DIR``: camera frames -> silhouettes -> contours -> joints.

Input: a frames folder (:mod:`silpose.app.inputs.frames_folder`)::

    DIR/background/<camera>/00000.png ...   (or <camera>.mp4|.avi) empty-scene frames, >= 2 per camera
    DIR/frames/<camera>/00000.png ...       (or <camera>.mp4|.avi) frames, same file names per camera

Camera folders are matched to the model's views by the rig's camera names. Per modelled camera a
background model is fitted on its background frames (:mod:`.segmentation`); each frame is
segmented (the paper's background subtraction), its outer contour extracted at the model's
``n_points`` (:mod:`.contours`), and the model infers joints and reconstructs every modelled
view's contour (:mod:`.inference`).

Missing views: a camera without a frames entry is missing for every frame; a frame whose
segmentation is empty, or whose largest blob is smaller than ``min_area`` pixels, is missing in
that view for that frame. The model marginalises missing views. Every (frame, camera) status is
recorded (``ok``, ``no video``, ``empty mask``, ``too small``; ``not modelled`` for a camera the
model was not trained on) and written to ``<out stem>.segmentation.json``; a frame with no usable
view gets NaN joints and ``n_views_present = 0``. ``--save-overlays`` draws one figure per frame
(:mod:`.overlays`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from silpose.model.persistence import load_model

from .contours import (
    DEFAULT_MIN_AREA,
    STATUS_EMPTY,
    STATUS_NO_CAMERA,
    STATUS_NOT_MODELLED,
    STATUS_OK,
    STATUS_SMALL,
    view_contour,
)
from .errors import FramesInputError
from .inference import TOP_K, InferOptions, apply_temporal, frame_status, infer_rows, merge_results, status_warnings
from .inputs.frames_folder import open_frames
from .overlays import OverlayWriter
from .segmentation import fit_backgrounds, segment_chunk
from .writers import sibling, write_contours, write_joints, write_segmentation


@dataclass
class FramesChunk:
    """One chunk of the pipeline, handed to ``on_chunk`` callbacks. n frames, K rig views.

    start: index of the chunk's first frame; names: (n,) frame names; images / masks: {camera:
    (n, H, W, 3) uint8 BGR / (n, H, W) bool} for the segmented cameras; contours: (n, K, n_pts, 2) px
    (NaN where missing); present: (n, K) bool; status: (n, K) str; result: the chunk's
    InferenceResult (rows of frames with no usable view are NaN).
    """

    start: int
    names: list
    images: dict
    masks: dict
    contours: np.ndarray
    present: np.ndarray
    status: np.ndarray
    result: object


@dataclass
class FramesResult:
    """Everything the pipeline produced for N frames and K rig views.

    frames: (N,) str names; cameras: rig camera names; contours: (N, K, n, 2) px (NaN where
    missing); present: (N, K) bool; status: (N, K) str; area: (N, K) int px of the largest blob
    (0 where missing); result: InferenceResult over the modelled views; timings: seconds per stage
    (background, read, segment, contours, infer).
    """

    frames: np.ndarray
    cameras: tuple
    contours: np.ndarray
    present: np.ndarray
    status: np.ndarray
    area: np.ndarray
    result: object
    timings: dict = field(default_factory=dict)


def run_frames_pipeline(model, root, *, chunk: int = 32, min_area: int = DEFAULT_MIN_AREA,
                        noise_variance: float | None = None, segment_params: dict | None = None,
                        on_chunk: Callable[[FramesChunk], None] | None = None,
                        progress: Callable[[int, int], None] | None = None,
                        options: InferOptions | None = None) -> FramesResult:
    """Segment, extract contours and infer on every frame of a frames folder (see the module docstring).

    Args:
        model: a fitted ShapeStructureModel with a rig.
        root: the frames folder.
        chunk: frames read, segmented and inferred together.
        min_area: smallest usable largest-blob area, px.
        noise_variance: observation noise s^2 (None = the model's).
        segment_params: keyword arguments of :class:`silpose.segment.BackgroundModel`.
        on_chunk: called with each :class:`FramesChunk` after its inference (overlays, evaluation).
        progress: called with (frames done, total).
        options: the model's inference options (:class:`~silpose.app.inference.InferOptions`; None = the
            plain posterior with ``noise_variance``). ``options.temporal`` applies to the whole sequence
            after the last chunk.
    Returns:
        :class:`FramesResult`.
    """
    folder = open_frames(model, root)
    names = list(model.rig_.names)
    K, n_pts, N = len(names), model.layout_.n_points, folder.n_frames
    modelled = {names[v] for v in model.layout_.views}
    cams = [c for c in folder.present if c in modelled]
    timings = dict.fromkeys(("background", "read", "segment", "contours", "infer"), 0.0)
    contours = np.full((N, K, n_pts, 2), np.nan)
    present = np.zeros((N, K), bool)
    status = np.full((N, K), STATUS_NO_CAMERA, dtype=object)
    area = np.zeros((N, K), np.int64)
    for c in folder.present:
        if c not in modelled:
            status[:, names.index(c)] = STATUS_NOT_MODELLED
    parts, order = [], []
    t0 = time.perf_counter()
    backgrounds = fit_backgrounds(folder, cams, segment_params)
    timings["background"] = time.perf_counter() - t0
    chunks = folder.iter_chunks(chunk)
    while True:
        t0 = time.perf_counter()
        try:
            start, images = next(chunks)
        except StopIteration:
            break
        timings["read"] += time.perf_counter() - t0
        n = len(next(iter(images.values())))
        rows = slice(start, start + n)
        t0 = time.perf_counter()
        masks = segment_chunk(backgrounds, images)
        timings["segment"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        for c in cams:
            k = names.index(c)
            for i in range(n):
                points, status[start + i, k], area[start + i, k] = view_contour(masks[c][i], n_pts, min_area)
                if points is not None:
                    contours[start + i, k] = points
                    present[start + i, k] = True
        timings["contours"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        res = infer_rows(model, contours[rows], present[rows], noise_variance, options)
        timings["infer"] += time.perf_counter() - t0
        parts.append(res)
        order.append(np.arange(start, start + n))
        if on_chunk is not None:
            on_chunk(FramesChunk(start, folder.frame_names[rows], images, masks, contours[rows], present[rows],
                                 status[rows], res))
        if progress is not None:
            progress(start + n, N)
    result = merge_results(parts, order, N)
    if options is not None and options.temporal:
        apply_temporal(result)
    return FramesResult(np.array(folder.frame_names), tuple(names), contours, present, status, area, result, timings)


def run_frames_inference(model_path: Path, root: Path, *, out: Path, save_contours: bool = False,
                         save_overlays: bool = False, overlay_dir: Path | None = None,
                         min_area: int = DEFAULT_MIN_AREA, noise_variance: float | None = None,
                         chunk: int = 32, progress: Callable[[int, int], None] | None = None,
                         robust: bool = True, temporal: bool = True) -> str:
    """Everything ``silpose infer MODEL --frames DIR`` does; returns a summary (several lines, ``warning:``
    lines last). Frames are a time sequence: with ``temporal`` the single answer of each frame is the Viterbi
    choice among its top-3 hypotheses (:func:`silpose.model.hypotheses.temporal_choice`)."""
    model_path, root, out = Path(model_path), Path(root), Path(out)
    if out.suffix.lower() not in (".parquet", ".json"):
        raise FramesInputError(f"{out}: the joints file must end in .parquet or .json")
    model = load_model(model_path)
    on_chunk = None
    if save_overlays:
        overlay_dir = Path(overlay_dir) if overlay_dir is not None else sibling(out, ".overlays")
        on_chunk = OverlayWriter(model, overlay_dir)
    options = InferOptions(noise_variance=noise_variance, hypotheses=TOP_K, robust=robust, untangle=True,
                           temporal=temporal)
    fr = run_frames_pipeline(model, root, chunk=chunk, min_area=min_area, noise_variance=noise_variance,
                             on_chunk=on_chunk, progress=progress, options=options)
    rig_names = list(model.rig_.names)
    status = frame_status(fr.result)
    write_joints(out, fr.frames, fr.result, rig_names, None, str(model_path), status=status)
    seg_path = sibling(out, ".segmentation.json")
    write_segmentation(seg_path, fr, root, min_area)
    lines = [f"{out}: joints of {len(fr.frames)} frames from {root}", f"{seg_path}: segmentation status per frame and camera"]
    if save_contours:
        cpath = sibling(out, ".contours.npz")
        write_contours(cpath, fr.frames, fr.result, rig_names)
        lines.append(f"{cpath}: reconstructed contours")
    if save_overlays:
        lines.append(f"{overlay_dir}/: {on_chunk.n_written} overlay figures")
    views = list(model.layout_.views)
    st = fr.status[:, views]
    none = int((~fr.present[:, views].any(axis=1)).sum())
    lines.append(
        f"views used {int((st == STATUS_OK).sum())} of {st.size}: {int((st == STATUS_NO_CAMERA).sum())} without a camera "
        f"folder, {int((st == STATUS_EMPTY).sum())} empty, {int((st == STATUS_SMALL).sum())} too small"
        + (f"; {none} frame(s) had no usable view (NaN joints)" if none else "")
    )
    t = fr.timings
    lines.append("seconds: " + ", ".join(f"{k} {v:.2f}" for k, v in t.items()))
    lines += status_warnings(fr.frames, status, getattr(model, "plausibility_", None) is not None)
    return "\n".join(lines)
