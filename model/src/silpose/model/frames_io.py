"""``silpose infer MODEL --frames DIR``: camera frames -> silhouettes -> contours -> joints.

Input: a frames folder (the "frames dataset" layout; :mod:`silpose.segment.frames_dir`)::

    DIR/background/<camera>/00000.png ...   (or <camera>.mp4|.avi) empty-scene frames, >= 2 per camera
    DIR/frames/<camera>/00000.png ...       (or <camera>.mp4|.avi) frames, same file names per camera

Camera folders are matched to the model's views by the rig's camera names. Per modelled camera a
:class:`silpose.segment.BackgroundModel` is fitted on its background frames; each frame is
segmented (the paper's background subtraction), its outer contour extracted with
:func:`silpose.shared.contours.extract_contour` at the model's ``n_points`` (the extraction the
training data went through; the model normalises the pixel contours itself, as in training), and
the model infers joints and reconstructs every modelled view's contour.

Missing views: a camera without a frames entry is missing for every frame; a frame whose
segmentation is empty, or whose largest blob is smaller than ``min_area`` pixels, is missing in
that view for that frame. The model marginalises missing views. Every (frame, camera) status is
recorded (``ok``, ``no camera``, ``empty``, ``too small``; ``not modelled`` for a camera the
model was not trained on) and written to
``<out stem>.segmentation.json``; a frame with no usable view gets NaN joints and
``n_views_present = 0``.

Dependencies: this module needs ``silpose.segment`` (imported lazily, so ``silpose.model`` stays
importable without it) and, for overlays, matplotlib (:mod:`silpose.model.frames_overlay`).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .inference_io import InferenceInputError, _write_atomic, write_contours, write_joints
from .persistence import load_model

STATUS_OK, STATUS_NO_CAMERA, STATUS_EMPTY, STATUS_SMALL = "ok", "no camera", "empty", "too small"
STATUS_NOT_MODELLED = "not modelled"
#: Default smallest usable blob, pixels (smaller blobs are noise, not a person).
DEFAULT_MIN_AREA = 50


class FramesInputError(InferenceInputError):
    """Bad ``--frames`` input; the message names the file or folder."""


def _segment():
    try:
        import silpose.segment as seg
    except ImportError as exc:  # pragma: no cover - the workspace installs it
        raise FramesInputError(
            "silpose infer --frames needs the silpose-segment package (background subtraction); "
            f"install it next to silpose-model ({exc})"
        ) from None
    return seg


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


def open_frames(model, root):
    """Validate a frames folder against the model's rig; returns a :class:`silpose.segment.frames_dir.FramesFolder`."""
    seg = _segment()
    from silpose.segment.frames_dir import FramesFolder

    if model.rig_ is None:
        raise FramesInputError("the model file stores no rig, so camera folders cannot be matched to views")
    rig = model.rig_
    try:
        return FramesFolder(root, rig.names, [(c.width, c.height) for c in rig])
    except seg.SegmentError as exc:
        raise FramesInputError(str(exc)) from None


def _nan_result(model, n: int):
    """An InferenceResult of ``n`` frames without any usable view: NaN everywhere, no view present."""
    from silpose.shared.skeleton import N_JOINTS

    from .shape_model import InferenceResult

    lay = model.layout_
    k, p, m = len(lay.views), lay.n_points, len(model.mixture_.weights_)
    nan = lambda *shape: np.full((n,) + shape, np.nan)  # noqa: E731
    return InferenceResult(joints=nan(N_JOINTS, 3), joints_best=nan(N_JOINTS, 3), joint_std=nan(N_JOINTS, 3),
                           contours_norm=nan(k, p, 2), contours_px=nan(k, p, 2), centroid=nan(k, 2), scale=nan(k),
                           views_present=np.zeros((n, k), bool), responsibilities=nan(m), log_marginal=nan(),
                           views=lay.views)


_ARRAY_FIELDS = ("joints", "joints_best", "joint_std", "contours_norm", "contours_px", "centroid", "scale",
                 "views_present", "responsibilities", "log_marginal")


def _merge(parts: list, order: list[np.ndarray], n: int):
    """Concatenate InferenceResults ``parts`` whose rows go to indices ``order[i]`` of an n-row result."""
    from .shape_model import InferenceResult

    ref = parts[0]
    arrays = {}
    for f in _ARRAY_FIELDS:
        a = getattr(ref, f)
        out = np.empty((n,) + a.shape[1:], a.dtype)
        for p, idx in zip(parts, order):
            out[idx] = getattr(p, f)
        arrays[f] = out
    return InferenceResult(**arrays, views=ref.views)


def _infer_rows(model, contours, present, noise_variance):
    """Infer on the rows with at least one modelled view; NaN rows elsewhere."""
    modelled = present[:, list(model.layout_.views)].any(axis=1)
    n = len(contours)
    if modelled.all():
        return model.infer(contours, present, noise_variance=noise_variance, input_views=range(model.n_rig_views_))
    if not modelled.any():
        return _nan_result(model, n)
    ok = np.flatnonzero(modelled)
    res = model.infer(contours[ok], present[ok], noise_variance=noise_variance, input_views=range(model.n_rig_views_))
    return _merge([res, _nan_result(model, n - len(ok))], [ok, np.flatnonzero(~modelled)], n)


def run_frames_pipeline(model, root, *, chunk: int = 32, min_area: int = DEFAULT_MIN_AREA,
                        noise_variance: float | None = None, segment_params: dict | None = None,
                        on_chunk: Callable[[FramesChunk], None] | None = None,
                        progress: Callable[[int, int], None] | None = None) -> FramesResult:
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
    Returns:
        :class:`FramesResult`.
    """
    seg = _segment()
    from silpose.shared.contours import EmptyMaskError, extract_contour

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
    try:
        t0 = time.perf_counter()
        bgs = {c: seg.BackgroundModel(**(segment_params or {})).fit(folder.background(c)) for c in cams}
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
            masks = {c: bgs[c].segment_batch(images[c]) for c in cams}
            timings["segment"] += time.perf_counter() - t0
            t0 = time.perf_counter()
            for c in cams:
                k = names.index(c)
                for i in range(n):
                    try:
                        ct = extract_contour(masks[c][i], n_pts)
                    except EmptyMaskError:
                        status[start + i, k] = STATUS_EMPTY
                        continue
                    area[start + i, k] = ct.area
                    if ct.area < min_area:
                        status[start + i, k] = STATUS_SMALL
                        continue
                    contours[start + i, k] = ct.points
                    present[start + i, k] = True
                    status[start + i, k] = STATUS_OK
            timings["contours"] += time.perf_counter() - t0
            t0 = time.perf_counter()
            res = _infer_rows(model, contours[rows], present[rows], noise_variance)
            timings["infer"] += time.perf_counter() - t0
            parts.append(res)
            order.append(np.arange(start, start + n))
            if on_chunk is not None:
                on_chunk(FramesChunk(start, folder.frame_names[rows], images, masks, contours[rows], present[rows],
                                     status[rows], res))
            if progress is not None:
                progress(start + n, N)
    except seg.SegmentError as exc:
        raise FramesInputError(str(exc)) from None
    result = _merge(parts, order, N)
    return FramesResult(np.array(folder.frame_names), tuple(names), contours, present, status, area, result, timings)


def write_segmentation(path: Path, fr: FramesResult, root: Path, min_area: int) -> None:
    """Per (frame, camera) segmentation status and blob area as JSON (written atomically)."""
    doc = {
        "frames_dir": str(root),
        "cameras": list(fr.cameras),
        "statuses": {STATUS_OK: "used", STATUS_NO_CAMERA: "no frames for this camera (missing view)",
                     STATUS_EMPTY: "segmentation found no foreground (missing view for this frame)",
                     STATUS_SMALL: f"largest blob under {min_area} px (missing view for this frame)",
                     STATUS_NOT_MODELLED: "the model does not use this camera"},
        "counts": {c: {s: int((fr.status[:, k] == s).sum()) for s in (STATUS_OK, STATUS_NO_CAMERA, STATUS_EMPTY,
                                                                       STATUS_SMALL, STATUS_NOT_MODELLED)} for k, c in enumerate(fr.cameras)},
        "frames": [{"frame": str(f), "status": [str(s) for s in fr.status[i]], "area_px": fr.area[i].tolist()}
                   for i, f in enumerate(fr.frames)],
    }
    _write_atomic(path, lambda p: p.write_text(json.dumps(doc, indent=1)))


def run_frames_inference(model_path: Path, root: Path, *, out: Path, save_contours: bool = False,
                         save_overlays: bool = False, overlay_dir: Path | None = None,
                         min_area: int = DEFAULT_MIN_AREA, noise_variance: float | None = None,
                         chunk: int = 32, progress: Callable[[int, int], None] | None = None) -> str:
    """Everything ``silpose infer MODEL --frames DIR`` does; returns a summary (several lines)."""
    model_path, root, out = Path(model_path), Path(root), Path(out)
    if out.suffix.lower() not in (".parquet", ".json"):
        raise FramesInputError(f"{out}: the joints file must end in .parquet or .json")
    model = load_model(model_path)
    stem = out.with_name(out.name.rsplit(".", 1)[0])
    on_chunk = None
    if save_overlays:
        from .frames_overlay import OverlayWriter  # checks matplotlib now, before any work

        overlay_dir = Path(overlay_dir) if overlay_dir is not None else stem.with_name(stem.name + ".overlays")
        on_chunk = OverlayWriter(model, overlay_dir)
    fr = run_frames_pipeline(model, root, chunk=chunk, min_area=min_area, noise_variance=noise_variance,
                             on_chunk=on_chunk, progress=progress)
    rig_names = list(model.rig_.names)
    write_joints(out, fr.frames, fr.result, rig_names, None, str(model_path))
    seg_path = stem.with_name(stem.name + ".segmentation.json")
    write_segmentation(seg_path, fr, root, min_area)
    lines = [f"{out}: joints of {len(fr.frames)} frames from {root}", f"{seg_path}: segmentation status per frame and camera"]
    if save_contours:
        cpath = stem.with_name(stem.name + ".contours.npz")
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
    return "\n".join(lines)
