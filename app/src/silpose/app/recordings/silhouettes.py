"""Per-camera foreground masks of a recording: decoded mask videos binarised, or colour videos segmented.

Mask videos (``--masks``): lossy codecs smear the 0/255 of a mask into grey edges, ringing and
blocks. :func:`binarise` takes a 3x3 median, then keeps grey levels above mid-grey (127). Measured on
the lab recording's cam1 masks (75 frames; :mod:`silpose.datagen.lab`) against the clean masks, mean
IoU for four encodings: mp4v alone 1.000 / JPEG q30 then mp4v 0.9985 / q15 then mp4v 0.9976 / q5,
blurred, then mp4v 0.9894; no extra connected component in any frame. A threshold at 40 instead
left 27-2,706 extra blobs (speckle) and IoU 0.91-0.98; Otsu per frame gave the same masks as
mid-grey within 0.0005 IoU at a higher cost. The median is for isolated salt pixels: at q5 it gains
0.0007 IoU and at q30 costs 0.0015.

Colour videos: the paper's background subtraction (:class:`silpose.segment.BackgroundModel`, one per
camera) with ``largest_blob=False`` (several people) and ``gain=True`` (each frame's lighting is matched
to the background's first: a plate shot at another time, auto-exposure), learnt from an empty-room clip per
camera (``--background DIR``: :data:`PLATE_FRAMES` frames from its middle, streamed through ``partial_fit``), from each video's first N frames
(``--background-frames N``; those frames then are not processed), or, when nobody leaves the room, from the
recording itself (``--background median``: the per-pixel median of :data:`MEDIAN_FRAMES` frames spread
over each video, :meth:`~silpose.segment.BackgroundModel.fit_robust`).

Masks are (H, W) uint8 in {0, 1}; :class:`MaskBinariser` and :class:`ColourSegmenter` are callables
``(camera, frame) -> mask`` with ``grey`` telling the reader which frames they want.
"""

from __future__ import annotations

import dataclasses
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from silpose.segment import BackgroundModel, Candidates, SegmentError, plate_alignment, plate_mismatch_std, warp_plate

from ..errors import RecordingError
from .sources import CameraReader, CameraSource, open_recording

#: grey levels above this are foreground in a mask video
MASK_THRESHOLD = 127
#: side of the median filter applied before the threshold (<= 1: none)
MASK_MEDIAN = 3
#: background frames read per camera at most from a recording's own first frames (``--background-frames N``)
MAX_BACKGROUND_FRAMES = 300
#: frames of an empty-room clip a camera's background is learnt from at most: that many consecutive frames from the
#: clip's middle (:func:`plate_start`). The statistics need no more: a per-pixel standard deviation from n frames is
#: within ~1 / sqrt(2 n) of its value (9 % at 60), and the clean-up filters take the specks a threshold a little low
#: lets through. Measured on the benchmark's 1920x1080 colour recording (4 cameras, 150 steps, the idle 2-core
#: machine) with empty-room clips of 300 frames: mean IoU against the true masks (every 5th frame) 0.9835 from the
#: 60 frames around the middle, 0.9836 from frames 10-289, at a set-up of 2.9-3.1 s against 7.3 s (all 300 frames:
#: 0.9846, 7.7-8.2 s; their first frame's mismatch with the recording's room view raised ``min_std`` from 2.0 to
#: 2.5-3.7, :func:`_fit_stream`). The middle: whoever started the camera is walking out of the picture at its start,
#: and back in at its end.
PLATE_FRAMES = 60
#: frames spread over a recording whose per-pixel median is its background (``--background median``)
MEDIAN_FRAMES = 41
#: frames spread over a recording's first :data:`ROOM_SPAN_S` seconds whose per-pixel median its empty-room clips
#: are registered to (:func:`room_view`)
ROOM_FRAMES = 9
#: seconds at the start of a recording that its room view (:func:`room_view`) is taken from: long enough for people
#: who walk to leave most pixels (a walker crosses ~2.5 m), short enough that the run keeps those frames for its
#: first steps instead of decoding them twice (:meth:`~.sources.CameraReader.read_ahead`); at most
#: :data:`ROOM_SPAN_MB` of frames at the working size per camera
ROOM_SPAN_S = 2.0
ROOM_SPAN_MB = 64
#: frames: :func:`spread_frames` decodes forward to a frame at most this far ahead rather than seeking (OpenCV's
#: FFmpeg seek decodes again from at least 16 frames before its target; measured on 30-frame 1932x1458 videos, nine
#: frames spread over them: 0.74 s of CPU per camera seeking to each)
SEEK_GAP = 32
#: frames: :func:`median_frames` sorts up to this many with a network (its cost grows as n^2), more with np.median
MEDIAN_NETWORK_MAX = 16
#: the value of ``--background`` that asks for the recording's own median
MEDIAN = "median"
#: BackgroundModel arguments of the recordings pipeline (the caller's ``segment_params`` override them)
SEGMENT_DEFAULTS = {"largest_blob": False, "gain": True}


def binarise(grey: np.ndarray, threshold: int = MASK_THRESHOLD, median: int = MASK_MEDIAN) -> np.ndarray:
    """(H, W) uint8 {0, 1} mask of a decoded (H, W) uint8 mask frame (module docstring)."""
    g = cv2.medianBlur(grey, median) if median > 1 else grey
    _, m = cv2.threshold(g, threshold, 1, cv2.THRESH_BINARY)
    return m


class MaskBinariser:
    """``(camera, grey frame) -> mask`` for mask videos."""

    grey = True

    def __init__(self, threshold: int = MASK_THRESHOLD, median: int = MASK_MEDIAN):
        self.threshold, self.median = int(threshold), int(median)

    def __call__(self, camera: str, frame: np.ndarray) -> np.ndarray:
        return binarise(frame, self.threshold, self.median)


class ColourSegmenter:
    """``(camera, BGR frame) -> mask`` for colour videos: one fitted BackgroundModel per camera."""

    grey = False

    def __init__(self, models: dict[str, BackgroundModel], warnings: list[str] | None = None):
        self.models = models
        self.warnings = list(warnings or [])  # lines for the user about the backgrounds' clips (a cut clip)

    def __call__(self, camera: str, frame: np.ndarray, candidates: Candidates | None = None) -> np.ndarray:
        """The mask of ``frame``; ``candidates``: :meth:`candidates` of it, computed beforehand (e.g. in the camera's
        reader thread), or None."""
        try:
            return self.models[camera].segment(frame, candidates=candidates).view(np.uint8)
        except SegmentError as exc:
            raise RecordingError(f"camera {camera!r}: {exc}") from None

    def candidates(self, camera: str, frame: np.ndarray) -> Candidates | None:
        """The whole-frame first steps of segmenting ``frame`` (:meth:`silpose.segment.BackgroundModel.candidates`):
        they change no model, so a camera's reader thread computes them for the frames it decodes ahead, beside the
        run's thread (:class:`~.sources.ThreadedReader`, ``after``); None where they cannot be (the run's thread then
        reports the error)."""
        try:
            return self.models[camera].candidates(frame)
        except SegmentError:
            return None


def plate_start(source: CameraSource, n: int) -> int:
    """The first of the ``n`` frames of an empty-room clip ``source`` that its background is learnt from: those
    around its middle (:data:`PLATE_FRAMES`); 0 when the clip is no longer or its length is unknown."""
    total = source.n_frames - source.skip if source.n_frames > 0 else 0
    return max(0, (total - int(n)) // 2)


def _fit_stream(source: CameraSource, n: int, params: dict, chunk: int = 32,
                room: CameraSource | CameraReader | None = None, view: Callable[[], np.ndarray | None] | None = None,
                start: int = 0, notes: dict[str, str] | None = None) -> BackgroundModel:
    """A BackgroundModel fitted on ``n`` frames of ``source`` from frame ``start`` on (streamed in chunks; a start
    within :data:`SEEK_GAP` frames is decoded up to, a farther one sought; when fewer than ``n`` follow it -- a cut file
    whose header announces more -- the frames from the first instead, with a line for the user in ``notes``
    {camera: line}); with ``room`` (the
    recording this is the background of), the frames are first registered to the recording's own view of the room
    (:func:`room_view`, :func:`silpose.segment.plate_alignment`; the warp, or None, is the model's ``plate_warp``)
    and the model's ``min_std`` is raised to the spread of the plate's differences from that view
    (:func:`silpose.segment.plate_mismatch_std`). ``view``: gives that room view (e.g. a future's result, computed
    elsewhere), asked for once the first chunk of the plate is read; None: :func:`room_view` of ``room`` here.
    The model's statistics are computed once, after the last chunk (``partial_fit(..., finalise=False)`` before)."""
    model = BackgroundModel(**{**SEGMENT_DEFAULTS, **params})
    reader = CameraReader(source, grey=False)
    if 0 < start <= SEEK_GAP:
        reader.skip(start)
    elif start > SEEK_GAP:
        reader.seek(start)
    seen = 0
    warp = None
    held: list[np.ndarray] = []  # the last chunk read: fitted with finalise=True once no other follows
    try:
        while seen < n:
            frames = []
            while len(frames) < min(chunk, n - seen):
                img = reader.read()
                if img is None:
                    break
                frames.append(img)
            if not frames:
                break
            if room is not None and seen == 0:
                seen_room = view() if view is not None else room_view(room)
                if seen_room is not None and seen_room.shape == frames[0].shape:
                    warp = plate_alignment(frames[0], seen_room)
                    aligned = frames[0] if warp is None else warp_plate(frames[0], warp)
                    model.min_std = max(model.min_std, plate_mismatch_std(aligned, seen_room))
            if warp is not None:
                frames = [warp_plate(f, warp) for f in frames]
            if held:  # another chunk follows it: only its sums (the statistics once, at the end)
                model.partial_fit(np.stack(held), finalise=False)
            held = frames
            seen += len(frames)
        if held:
            model.partial_fit(np.stack(held))
    except SegmentError as exc:
        raise RecordingError(f"{source.path}: {exc}") from None
    finally:
        reader.close()
    if start > 0 and seen < n:  # the clip ended before its header said (a cut file): its frames from the first
        model = _fit_stream(source, n, params, chunk, room, view, start=0)
        if notes is not None:
            notes[source.camera] = (
                f"{source.path}: this empty-room clip stops decoding at frame {reader.ended_at} of the {source.n_frames}"
                f" its header announced (a cut or corrupt file): camera {source.camera!r}'s background is learnt from "
                f"its first {model.n_frames_seen_} frames, not its middle")
        return model
    if seen < 2:
        raise RecordingError(f"{source.path}: a background needs at least 2 frames, found {seen}")
    model.plate_warp = warp
    return model


def spread_frames(source: CameraSource, n: int) -> list[np.ndarray]:
    """Up to ``n`` colour frames spread evenly over ``source`` (fewer when it is shorter)."""
    total = source.n_frames - source.skip if source.n_frames > 0 else n * 10
    picks = sorted(set(np.linspace(0, max(total - 1, 0), min(n, max(total, 1))).round().astype(int).tolist()))
    reader = CameraReader(source, grey=False)
    frames = []
    at = 0  # the frame the next read gives
    try:
        for i in picks:
            if 0 <= i - at <= SEEK_GAP:  # near: decode forward (module constant)
                reader.skip(i - at)
            else:
                reader.seek(i)
            img = reader.read()
            at = i + 1
            if img is not None:
                frames.append(img)
    finally:
        reader.close()
    return frames


def median_frames(frames: list[np.ndarray]) -> np.ndarray:
    """The per-pixel median of ``frames`` (n arrays of one shape, uint8): ``np.median(np.stack(frames),
    axis=0).astype(np.uint8)`` exactly (for even n the two middle values' mean, rounded down), computed for
    n <= :data:`MEDIAN_NETWORK_MAX` by an odd-even transposition sorting network of elementwise minima and
    maxima (n (n - 1) / 2 compare-exchanges of whole frames; measured on nine 716x541 BGR frames: 22 ms against
    np.median's 286 ms, which partitions every pixel's values apart)."""
    n = len(frames)
    if n > MEDIAN_NETWORK_MAX:
        return np.median(np.stack(frames), axis=0).astype(np.uint8)
    s = [np.asarray(f, np.uint8) for f in frames]
    for p in range(n):
        for i in range(p % 2, n - 1, 2):
            lo = np.minimum(s[i], s[i + 1])
            s[i + 1] = np.maximum(s[i], s[i + 1])
            s[i] = lo
    if n % 2:
        return s[n // 2].copy()
    return ((s[n // 2 - 1].astype(np.uint16) + s[n // 2]) // 2).astype(np.uint8)


def room_span(source: CameraSource) -> int:
    """Frames at the start of ``source`` that its room view is taken from: :data:`ROOM_SPAN_S` seconds (an unknown
    frame rate taken as 25), no more than :data:`ROOM_SPAN_MB` of its frames as read (colour, at ``resize_to``
    when set), at least :data:`ROOM_FRAMES`."""
    w, h = source.resize_to or (source.width, source.height)
    fps = source.fps if source.fps and source.fps > 0 else 25.0
    fit = ROOM_SPAN_MB * 2**20 // max(1, 3 * int(w) * int(h))
    return int(max(ROOM_FRAMES, min(round(ROOM_SPAN_S * fps), fit)))


def room_view(recording: CameraSource | CameraReader, n: int = ROOM_FRAMES) -> np.ndarray | None:
    """The recording's own view of the room: the per-pixel median of ``n`` frames spread over its first
    :func:`room_span` frames (people who move are not in it), uint8; None with fewer than 3 frames.
    ``recording``: its source (read by a reader of its own), or the run's reader of it, which keeps the frames it
    read for the run (:meth:`~.sources.CameraReader.read_ahead`)."""
    own = isinstance(recording, CameraSource)
    reader = CameraReader(recording, grey=False) if own else recording
    try:
        frames = reader.read_ahead(room_span(reader.source))
    finally:
        if own:
            reader.close()
    picks = sorted(set(np.linspace(0, len(frames) - 1, min(n, len(frames))).round().astype(int).tolist())) if frames else []
    return median_frames([frames[i] for i in picks]) if len(picks) >= 3 else None


def background_from_clips(folder: Path, rig, cameras, params: dict | None = None,
                          sizes: dict[str, tuple[int, int]] | None = None,
                          recording: dict[str, CameraSource | CameraReader] | None = None) -> ColourSegmenter:
    """Background models of ``cameras`` learnt from the empty-room clips in ``folder`` (same layout and
    names as the videos folder: ``<camera>.mp4``, ``<camera>/`` frames, or ``<camera>/background.avi`` in a
    camera folder holding several videos), at each camera's working size ``sizes`` (width, height; None:
    the rig camera's size); with ``recording`` ({camera: source, or the run's reader of it, at the same sizes}),
    each clip is registered to its recording's room view first (:func:`room_view`, :mod:`silpose.segment.align`)."""
    clips = open_recording(folder, rig, role="background")
    absent = [c for c in cameras if c not in clips.sources]
    if absent:
        raise RecordingError(f"{folder}: no empty-room clip for camera(s) {', '.join(absent)} (expected "
                             f"{folder / (absent[0] + '.mp4')})")
    sources = {c: at_size(clips.sources[c], (sizes or {}).get(c)) for c in cameras}
    notes: dict[str, str] = {}
    return ColourSegmenter(_fit_all(sources, PLATE_FRAMES, params or {}, recording, middle=True, notes=notes),
                           [notes[c] for c in cameras if c in notes])


def _fit_all(sources: dict[str, CameraSource], n: int, params: dict,
             rooms: dict[str, CameraSource | CameraReader] | None = None, middle: bool = False,
             notes: dict[str, str] | None = None) -> dict[str, BackgroundModel]:
    """{camera: :func:`_fit_stream` of its source}: its first ``n`` frames, or with ``middle`` the ``n`` around its
    middle (:func:`plate_start`); in a pool of threads (at most the CPU count): decoding,
    resizing and summing release the GIL, so the cameras' backgrounds are learnt side by side; the models are those
    of one camera after the other (each fits its own). With ``rooms``, every camera's room view (:func:`room_view`:
    decoding the recording's first frames) is a task of its own, submitted first, and each camera's plate is read and fitted in another once the pool is free: the pool's
    threads take work of about one size, not two cameras' whole set-ups each, so neither waits long for the other
    at the end."""
    rooms = rooms or {}
    workers = max(1, min(len(sources), os.cpu_count() or 1))
    starts = {c: plate_start(sources[c], n) if middle else 0 for c in sources}
    if workers == 1:
        return {c: _fit_stream(sources[c], n, params, room=rooms.get(c), start=starts[c], notes=notes) for c in sources}
    with ThreadPoolExecutor(max_workers=workers) as pool:
        # the room views first: a plate's task then finds its view computed (or being computed) when it asks for it
        views = {c: pool.submit(room_view, rooms[c]) for c in sources if c in rooms}
        fits = [pool.submit(_fit_stream, sources[c], n, params, room=rooms.get(c),
                            view=views[c].result if c in views else None, start=starts[c], notes=notes)
                for c in sources]
        fitted = [f.result() for f in fits]
    return dict(zip(sources, fitted))


def at_size(source: CameraSource, size: tuple[int, int] | None) -> CameraSource:
    """``source`` read at ``size`` (width, height): its frames resized when that is not their own size."""
    if size is None:
        return source
    size = (int(size[0]), int(size[1]))
    return dataclasses.replace(source, resize_to=None if size == (source.width, source.height) else size)


def background_from_first_frames(sources: dict[str, CameraSource], n: int, params: dict | None = None) -> ColourSegmenter:
    """Background models learnt from the first ``n`` (>= 2) frames of each camera's video."""
    if n < 2:
        raise RecordingError(f"--background-frames: a background needs at least 2 frames, got {n}")
    return ColourSegmenter(_fit_all(sources, n, params or {}))


def background_from_recording(sources: dict[str, CameraSource], params: dict | None = None,
                              n: int = MEDIAN_FRAMES) -> ColourSegmenter:
    """Background models learnt from the recording itself: the per-pixel median of ``n`` frames spread evenly
    over each camera's video (module docstring); people who move are not in it, someone who stands still
    for more than half of the recording is."""
    models = {}
    for c, src in sources.items():
        frames = spread_frames(src, n)
        if len(frames) < 3:
            raise RecordingError(f"{src.path}: a background from the recording needs at least 3 frames, found {len(frames)}")
        try:
            models[c] = BackgroundModel(**{**SEGMENT_DEFAULTS, **(params or {})}).fit_robust(np.stack(frames))
        except SegmentError as exc:
            raise RecordingError(f"{src.path}: {exc}") from None
    return ColourSegmenter(models)
