"""``silpose infer MODEL --videos DIR``: per-camera videos of several people -> each person's joints in the room.

Per time step (the steps are processed in chunks of ``chunk``; nothing grows with the recording's length
except a few numbers per person and step for the floor plan):

1. every camera's next frame is decoded and turned into a mask (:mod:`.sources`, :mod:`.silhouettes`) and
   its connected components found (:mod:`.blobs`) -- per camera, in a thread pool (OpenCV releases the GIL);
2. people are found on the floor by the occupancy grid of all masks (:mod:`.floor`) and linked into
   tracks (:mod:`.tracking`);
3. each camera's mask cut down to the detected people's visual hulls (:mod:`.hull`: clutter that touches a
   person in one camera has no support in the others); per person and camera, the blob of the cut mask that is
   theirs alone, or the reason there is none (:mod:`.views`), and the share of their blob that was cut; their
   contours (:func:`silpose.shared.contours.extract_contour` on the blob);
then per chunk:
4. the model infers every detected person's root-relative joints from their usable views, missing views
   marginalised (:func:`silpose.app.inference.infer_rows`, as for one person, :mod:`.one_person`); a person
   with no usable view gets no joints; once the next chunk is inferred too, each person's answer is chosen among
   their hypotheses along their track (:func:`.chunk_rows.choose_along_tracks`), so a chunk is placed, drawn and
   queued for writing one chunk later (its camera frames held that long for the overlays: 4 colour cameras at
   1920x1080 with overlays, 150 steps, peak memory 1.59 GB before, 1.67 and 1.72 GB in two runs after);
5. the root is placed in the room and the missing views' contours are projected (:mod:`.placement`), each
   joint moved inside the person's outline in every used view (:mod:`.silhouette_fit`); joints are written in silpose's frame and in the calibration's (:mod:`.room`, :mod:`.writers`);
6. overlay videos (:mod:`.overlay_video`); at the end the floor plan (:mod:`.floorplan`; drawn by a worker process
   started at the set-up when this process has not imported matplotlib yet, :mod:`.floorplan_worker`) and
   ``summary.json``.

Threads: on a machine of 3 cores or more (:data:`POOL_MIN_CORES`) the per-camera stages run in a pool of one thread
per camera (at most the CPU count), on 1-2 cores in the run's thread (on 2 cores with each camera decoding in a
reader thread of its own, :data:`READER_MIN_CORES`) -- except the view
stage (3) of mask videos without carving, which runs in the run's thread: it is small numpy calls that hold the
GIL, and a pool round trip per stage cost more than it gave (lab recording, 90 steps, six alternating runs at
load ~5: 19.2 CPU ms per step and 49 steps/s on average, 21.1 and 47 through the pool); there, each camera's next
step is started in the pool as soon as the current one is handed over (:mod:`.lookahead`), so the decoding and
labelling of step t + 1 overlap the floor and view stages of step t, with the same results (lab recording played
3x, 180 steps, nine alternating pairs at load 5-12: faster in 7 of them, median ratio 1.14, mean 35.1 vs 31.2
steps/s, 18.2 vs 19.6 CPU ms per step; the wall figures swing by 2x with the other jobs). Colour videos do the same in a pool of their own (their view stage uses the first): a step
segmented ahead is segmented again when static clutter became background in between (4 x 1932x1458, 60 steps,
load 12-14: 2.92 steps/s and 166 CPU ms per step, 2.58 and 189 before; the same joints.csv) -- and BLAS
is held to one thread during the run: the model's batches here are small (a chunk's people), and BLAS
threads competing with the camera threads cost more than they give (measured on this 2-core machine
under load: inference of 150 steps took 2.65 s with OpenBLAS's 2 threads, 0.68 s with 1); so are OpenCV's own
parallel loops (``cv2.setNumThreads(1)``, restored after the run) and FFmpeg's decoding threads
(:data:`~.sources.DECODER_PARAMS`): the cameras already run in threads of their own.
Colour videos decode in reader threads of their own (:class:`~.sources.ThreadedReader`), which with the run's
thread keep two cores busy: the camera pool is then one thread per camera, at most the CPU count less two, so
none on a 2-core machine (the segmentation, the floor and the views in the run's thread, the decoding still beside
it). Measured on the benchmark's colour recording (4 x 1932x1458, 150 steps, three alternating runs on the idle
2-core machine): 15.9 / 15.3 / 16.9 time steps/s and 14.1 / 14.5 / 13.2 CPU s without the pool, 14.0 / 12.8 / 13.4
and 17.3 / 18.4 / 17.8 with it, the same joints.csv -- six threads that take turns at the GIL cost more than the
overlap gives (the floor's occupancy map, 0.4 CPU ms of numpy, took 5-6 ms of wall time per step beside them).
Each reader thread also takes the first steps of its frames' segmentation, which release the GIL and change no
model: the gain's division and the candidates (:meth:`~.silhouettes.ColourSegmenter.candidates`, handed over with
the frame; the run's thread computes them again when static clutter became background since,
:attr:`silpose.segment.BackgroundModel.version`). Measured on the benchmark's colour recordings (150 steps, the idle
2-core machine, alternating runs, the same joints.csv): 1920x1080, 16.0 / 15.9 / 15.0 / 14.6 / 14.2 / 16.3 / 14.4
time steps/s against 16.7 / 14.3 / 14.3 / 13.1 / 15.8 / 14.2 / 13.7 with the run's thread doing them; 1932x1458,
16.6 / 14.4 / 16.5 against 14.6 / 14.6 / 14.9. Mask videos keep their whole camera stage in the run's thread: with
each frame binarised in its reader thread, the lab recording played 3x (450 steps, three alternating pairs) ran at
95.0 / 97.3 / 80.4 time steps/s against 109.2 / 105.0 / 113.5 (binarised and labelled there: 87.7 / 78.4 / 72.8
against 112.0 / 115.9 / 90.0), the threads taking turns at the GIL.

Set-up (before the first step; ``setup`` of the run's timings): the videos are probed a thread each
(:func:`~.sources.probe_all`); each camera's reader is opened -- and, in its thread, decodes its first frames --
while the backgrounds are learnt, and the floor grid is built meanwhile, since none of them needs a background;
the backgrounds of colour videos are learnt in a pool where each camera's room view (the plate registration's
view of the room, :func:`~.silhouettes.room_view`) is a task of its own (:mod:`.silhouettes`). The room view is
the median of 9 frames spread over the recording's first 2 s (at most 64 MB of frames per camera), read through the run's own reader, which keeps them
for the first steps (:meth:`~.sources.CameraReader.read_ahead`; its thread starts once the backgrounds are learnt):
no frame is decoded twice. It was the median of frames spread over the whole video, reached by decoding every
frame up to the last pick once more -- most of a colour run's set-up. Measured on the benchmark's colour recording
(4 x 1932x1458 MPEG-4, 150 steps, three alternating pairs on the idle machine): 14.4 / 15.2 / 15.9 time steps/s
and 16.9 / 16.2 / 15.4 CPU s, against 12.2 / 12.5 / 13.0 and 20.0 / 19.5 / 19.1 before.

Rows of a track are held back until the track is a person or dropped (``Tracker.decided_within`` steps): a
detection that never becomes a person leaves no rows. Input problems found before the run (a folder, a video, a size, a frame
rate, an option) are one-line :class:`~silpose.app.errors.RecordingError`; what happens during the run
(an empty mask, a video that stops, a person in no usable view) becomes a status, never an error.

Static clutter (colour videos): what the background clip did not hold -- a chair moved since, a bag, someone
standing still at the back -- is foreground that no person explains. Per camera, a pixel that has been
foreground outside the image box of every person on the floor (a track the tracker confirmed;
:func:`~.views.body_box`: the cylinder of radius :data:`~.camera_step.PROTECT_RADIUS_M` and height 2.2 m standing at their floor
point) for :data:`ABSORB_S` seconds -- the frames it spends inside a box do not count, but do not reset its count
either; a frame where it is background does -- becomes
background (:meth:`silpose.segment.BackgroundModel.absorb`, with its values in that frame). Persons are protected
by their box, however still they stand; clutter touching a person's box is absorbed outside it, so their blob
again fits their box. Tentative tracks and the floor grid's ghosts protect nothing (a newcomer's pixels age for the
0.3 s before they are confirmed, of the 2 s). Who becomes a person in colour videos (:func:`~.step_people.may_be_person`, the
tracker's ``may_confirm``; mask videos absorb nothing, so there every track the tracker confirms is one): a track
that has walked :data:`~.tracking.TRAVEL_M`, or one that some camera has seen alone (a usable view of its own; a
ghost lives on other people's blobs) -- in the workspace at once; in the margin the floor grid searches around it
(:data:`.floor.MARGIN_M`) once it has outlived the absorption (:func:`margin_wait`: clutter standing there has become
background by then and its track has ended), or when the recording ends first (a clip too short to tell, such as
Pose2Sim's 1.7 s demo, whose two people stand up to 0.4 m outside its imported workspace). Rows are held back that
long. A track beyond both that has not walked (:func:`~.step_people.static_clutter`) takes no views -- a blob it shares
with a person is the person's -- and never protects: someone who stands still at the back all along becomes
background, not a person ("persistent static blobs become background, not people"; cameras on one wall may place
them in the margin, ``tests/app/recordings/test_rooms.py``, ``still``). The price: someone who stays in the margin
moving in place is unprotected for those seconds, and the pixels they always cover become background. Before any of this, the floor grid's ghosts are explained away by the
people found before them (:mod:`.ghosts`): where clutter is absorbed, a ghost that lasts protects it and shares
the people's blobs. Not in mask videos, where nothing is absorbed: on the four-walker lab recording
(:data:`silpose.datagen.lab.FOUR_WALKERS`, 200 frames, masks) explaining away took the rows off every true person
from 8 to 1 but cost an id (5 instead of 4), a switch (11 vs 10) and 12 person-frames found (634 vs 646): walkers
emerging from the group, hidden behind the others in all but one camera, were found later.

At the end each camera's masks are judged over the run (:meth:`~.camera_step.CameraStep.diagnosis`): a camera with no foreground in
90 % of its frames, or foreground over half the image in 90 % of them, gets a warning line naming the likely
cause -- mask videos storing foreground as 1 instead of 255, inverted masks (people black on white), the wrong
video or background clip, a lighting change -- since such a run otherwise ends with "nobody was found".
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import cv2
import numpy as np
from threadpoolctl import threadpool_limits

from silpose.model.persistence import load_model
from silpose.shared.atomic import write_json_atomic
from silpose.shared.skeleton import JOINT_NAMES

from ..errors import RecordingError
from ..inference import TOP_K
from .camera_step import CameraStep, Seen, shown
from .chunk_rows import ChunkInference, choose_along_tracks, draw_chunk, emit_rows, infer_people, place_chunk
from .floor import FloorGrid, capture_bounds
from .floorplan import write_floorplan
from .floorplan_worker import floorplan_process
from .hull import PersonHulls
from .lookahead import StepAhead
from .frames_source import bad_frame, frames_folder_run
from .overlay_png import overlay_sink
from .resolution import WORK_PERSON_PX, min_blob_area, work_camera, work_size
from .pages import ordinary_pages
from .silhouettes import (MEDIAN, MaskBinariser, at_size, background_from_clips, background_from_first_frames,
                          background_from_recording)
from .sources import CameraReader, ThreadedReader, holds_background_clips, open_recording, parse_offsets
from .step_people import Person, margin_wait, may_be_person, step_people
from .tracking import CONFIRM_S, Track, tracker_for_fps
from .views import VIEW_ENDED, VIEW_NO_VIDEO, VIEW_OK, VIEW_STATUSES
from .writers import PersonRows, RecordingWriter

#: seconds: foreground that stays this long outside every detected person's body box becomes background
ABSORB_S = 2.0
#: CPU cores below which the cameras' stages run in the run's thread (no camera pool) unless the options say
#: otherwise: on 2 cores the pool's threads, the run's own and OpenCV's contend for the cores and the GIL. Mask
#: videos, the idle project machine (2-core AMD EPYC), alternating runs: the lab recording (150 steps) 67.7 / 69.9 /
#: 71.6 time steps/s without the pool against 65.5 / 73.4 / 63.7 with 2 threads, played 3x (450 steps) 67.2 / 87.9 /
#: 84.2 against 65.6 / 77.5 / 55.7, with mp4 overlays 39.9 / 44.2 / 36.4 against 37.0 / 39.6 / 37.2, and 25-35 % less
#: CPU per step in every pair (15.8-16.3 against 19.1-21.9 ms; the benchmark's "1x single-threaded" row has shown the
#: same in 4 of its last 5 runs). Under load 5-12 the pool had been faster (module docstring, "Threads"): more runnable
#: threads take a larger share of a machine others use, at a higher cost in CPU.
POOL_MIN_CORES = 3
#: CPU cores from which mask videos, too, decode in reader threads of their own (:func:`default_reader_threads`):
#: a mask frame decodes in ~0.3 ms, which on one core only takes turns with the run's thread. The lab recording played
#: 3x (450 steps, lossy 644x486 mask videos), the idle 2-core project machine, three alternating runs: 100.1 / 100.1 /
#: 101.0 time steps/s with them against 91.5 / 90.8 / 91.1 without (12.4 against 11.6 CPU ms per step); beside two
#: busy processes 59.6 / 60.1 against 56.0 / 56.9, the same joints.csv.
READER_MIN_CORES = 2


@dataclass
class RecordingOptions:
    """Options of :func:`run_recording` (``silpose infer --videos``) and of :func:`.one_person.run_one_person`.

    masks: the videos are foreground masks (else colour, segmented against ``background`` clips -- or the
    recording's own median when ``background`` is ``"median"`` -- or the first ``background_frames`` frames);
    offsets: ``"cam1=3,cam2=-0.12s,..."`` (frames or seconds); min_area: px of the rig camera (None:
    :func:`~.resolution.min_blob_area`'s share
    of a person); overlays: ``"mp4"`` (or True: per-camera overlay videos), ``"png"`` (one tiled PNG per frame,
    :mod:`.overlay_png`) or ``"none"`` (or False); noise_variance: the model's s^2 when None; chunk: steps per
    inference batch; threads:
    per-camera worker threads (None: one per camera, at most the CPU count, less two with reader threads,
    none on 1-2 cores, :data:`POOL_MIN_CORES`; 0: none, module docstring "Threads"); max_steps: stop after
    that many steps; segment_params: ``BackgroundModel`` keyword arguments; min_hits / max_misses: tracking, steps
    (:class:`~silpose.app.recordings.tracking.Tracker`; None: :func:`~silpose.app.recordings.tracking.tracker_for_fps`'s
    0.3 s and 4 s).
    contours: also write every view's reconstructed contour (``contours_px``) to joints.parquet.
    appearance: tell people apart by their looks too (:mod:`.appearance`: stature, width, colours) where
    motion cannot (merges, re-identification); False: motion alone. max_people: at most this many ids
    (``--max-people``; 0: no limit): a new person beyond that takes the id of the most alike lost one.
    robust: robust inference (``silpose.model.robust``: contour points far from the reconstruction are
    down-weighted); None = on for colour videos (silpose's segmentation leaves holes, blobs and shadows), off
    for mask videos (measured on the lab recording of :mod:`silpose.datagen.lab`, M 10 q 30 model: world-frame
    error 5.8 cm without, 6.3 cm with; 115 vs 87 time steps/s). hypotheses: top-K kept per person-frame (at least
    :data:`silpose.model.hypotheses.TEMPORAL_HYPOTHESES`), the answer the hypothesis chosen along each track, a chunk
    at a time with the next chunk ahead (:func:`.chunk_rows.choose_along_tracks`); 0 = the posterior mean. work_person_px: frames are
    processed at the size where a person is about this tall (:mod:`.resolution`; 0: the rig camera's size).
    absorb_s: colour videos: seconds after which foreground outside every person's box becomes background
    (module docstring; 0: never). overlay_dir: the overlays' folder (None: ``out/overlays``). carve: cut each person's
    views down to their visual hull before the views are judged (:mod:`.hull`); None = for colour videos only (the
    clutter it cuts comes from background plates older than the recording; on the lab's mask videos it changed no
    joint and cost 1.24-1.96x the CPU per step, benchmark ``recordings``). reader_threads:
    decode each camera in its own thread, frames ahead
    (:class:`~.sources.ThreadedReader`); None = :func:`default_reader_threads` (colour videos; mask videos on 2
    cores).
    align_plates: register each empty-room clip to the recording's own view of the room before its background
    is learnt (:mod:`silpose.segment.align`: a camera nudged or a video rescaled since the plate).
    silhouette_fit: move each placed joint, as little as its posterior standard deviation allows, inside the
    outlines of the views used (:mod:`.silhouette_fit`).
    """

    masks: bool = False
    background: Path | None = None
    background_frames: int | None = None
    offsets: str | None = None
    min_area: int | None = None
    overlays: bool | str = True
    noise_variance: float | None = None
    chunk: int = 16
    threads: int | None = None
    max_steps: int | None = None
    segment_params: dict | None = None
    min_hits: int | None = None
    max_misses: int | None = None
    contours: bool = False
    appearance: bool = True
    max_people: int = 0
    robust: bool | None = None
    hypotheses: int = TOP_K
    work_person_px: int = WORK_PERSON_PX
    absorb_s: float = ABSORB_S
    reader_threads: bool | None = None
    overlay_dir: Path | None = None
    align_plates: bool = True
    carve: bool | None = None
    silhouette_fit: bool = True


@dataclass
class RecordingSummary:
    """What a run did. files: written paths; counts: rows per status; views_hist: person-frames on the floor
    by number of usable views (index = views); camera_status: {camera: {status: frames}}; timings: seconds per
    stage (``cameras`` ... ``overlays``, the run's thread), ``setup`` (before the first step: opening the videos,
    learning backgrounds), ``finish`` (after the last step: closing the files, the floor plan) and ``total``;
    n_steps, n_persons, warnings; inside: the mean share of joints inside their own silhouettes in the views
    used, over the rows with joints (the ``inside`` column; NaN: none)."""

    out: Path
    files: list[Path]
    n_steps: int
    n_persons: int
    counts: dict
    views_hist: list[int]
    camera_status: dict
    timings: dict
    warnings: list[str] = field(default_factory=list)
    inside: float = float("nan")

    @property
    def steps_per_second(self) -> float:
        total = self.timings.get("total", 0.0)
        return self.n_steps / total if total > 0 else float("nan")

    @property
    def steady_steps_per_second(self) -> float:
        """Time steps per second between the first step and the last (``total`` without ``setup`` and
        ``finish``): the rate a long recording approaches."""
        t = self.timings.get("total", 0.0) - self.timings.get("setup", 0.0) - self.timings.get("finish", 0.0)
        return self.n_steps / t if t > 0 else float("nan")

    def text(self) -> str:
        on_floor = sum(self.views_hist)
        frac = [sum(self.views_hist[k:]) / on_floor if on_floor else float("nan") for k in range(len(self.views_hist))]
        lines = [f"{self.out}: {self.n_persons} person(s) over {self.n_steps} frames; "
                 + ", ".join(f"{n} rows {s}" for s, n in self.counts.items() if n)]
        if on_floor:
            lines.append("person-frames with >= 1/2/3/4 usable views: " + " / ".join(f"{100 * f:.0f} %" for f in frac[1:5]))
        if self.inside == self.inside:
            lines.append(f"joints inside their own silhouettes in the views used: {self.inside:.3f} (the inside column)")
        lines += [f"wrote {p}" for p in self.files]
        lines.append(f"{self.steps_per_second:.1f} time steps/s; seconds: " + ", ".join(f"{k} {v:.2f}" for k, v in self.timings.items()))
        return "\n".join(lines)


def default_reader_threads(masks: bool) -> bool:
    """Whether each camera decodes in a reader thread of its own when the options do not say: colour videos always
    (their decoding is most of a step); mask videos on :data:`READER_MIN_CORES` cores or more where there is no camera
    pool (:data:`POOL_MIN_CORES`: with one, each camera's next step, its decoding included, already runs ahead in the
    pool)."""
    cores = os.cpu_count() or 1
    return (not masks) or READER_MIN_CORES <= cores < POOL_MIN_CORES


def default_camera_threads(n_cameras: int, reader_threads: bool) -> int:
    """Camera worker threads when the options do not say (module docstring, "Threads"): one per camera, at most the
    CPU count, less two when the cameras decode in reader threads of their own (one core for them, one for the run's
    thread); 0 on a machine of at most 2 cores either way (:data:`POOL_MIN_CORES`)."""
    cores = os.cpu_count() or 1
    if cores < POOL_MIN_CORES:
        return 0
    return max(0, min(n_cameras, cores - 2 if reader_threads else cores))


def run_recording(model, videos, out, options: RecordingOptions | None = None, *,
                  progress: Callable[[int, int], None] | None = None, warn: Callable[[str], None] | None = None,
                  model_path: str = "") -> RecordingSummary:
    """Everything ``silpose infer MODEL --videos DIR --out OUT`` does (module docstring).

    Args:
        model: a fitted ShapeStructureModel with a rig, or the path of a model file.
        videos: the videos folder (:mod:`.sources`). out: output folder (created).
        options: :class:`RecordingOptions`. progress: called with (steps done, total or -1).
        warn: called with each warning line when it is found (also in the summary).
    numpy allocates in ordinary pages during the run (:func:`.pages.ordinary_pages`).
    """
    with ordinary_pages():
        return _run(model, videos, out, options, progress=progress, warn=warn, model_path=model_path)


def _run(model, videos, out, options: RecordingOptions | None, *, progress: Callable[[int, int], None] | None,
         warn: Callable[[str], None] | None, model_path: str) -> RecordingSummary:
    """:func:`run_recording`'s work."""
    t_start = time.perf_counter()
    opt = options or RecordingOptions()
    if isinstance(model, (str, Path)):
        model_path = model_path or str(model)
        model = load_model(Path(model))
    if getattr(model, "rig_", None) is None:
        raise RecordingError("the model file stores no rig, so videos cannot be matched to cameras")
    videos, opt, frame_names = frames_folder_run(videos, opt, model.rig_)
    check_background_options(opt, videos, model.rig_)
    if opt.chunk < 1 or (opt.min_area is not None and opt.min_area < 1):
        raise RecordingError("chunk and min_area must be >= 1")
    rig = model.rig_
    names = list(rig.names)
    transform, workspace = rig.transform, rig.workspace
    recording = open_recording(videos, rig, parse_offsets(opt.offsets, names))
    warnings = list(recording.warnings)
    for w in warnings:
        if warn:
            warn(w)

    lay = model.fitted_layout()
    modelled = [names[v] for v in lay.views]
    n_pts = lay.n_points
    # every camera at its working resolution (module .resolution): geometry, masks and overlays at that size,
    # contours scaled back to the rig camera's pixels for the model
    work = [work_camera(c, work_size(c, workspace.center, opt.work_person_px)) for c in rig]
    sources = {c: at_size(s, (work[names.index(c)].width, work[names.index(c)].height))
               for c, s in recording.sources.items()}
    start = first_step(opt)
    threaded = default_reader_threads(opt.masks) if opt.reader_threads is None else bool(opt.reader_threads)
    reader = (lambda r: ThreadedReader(r)) if threaded else (lambda r: r)  # noqa: E731
    # the cameras' readers open (and, in threads, decode ahead) while the backgrounds are learnt, and the floor grid
    # is built meanwhile: neither needs a background (module docstring, "Set-up")
    readers: dict = {}
    # plates registered to the room views of the recording's first frames: the run's own readers read those frames
    # (and keep them for the first steps), their threads start after (module docstring, "Set-up")
    rooms = opt.background is not None and str(opt.background) != MEDIAN and opt.align_plates and not opt.masks
    try:
        for c, src in sources.items():
            readers[c] = CameraReader(src, opt.masks, start) if rooms else reader(CameraReader(src, opt.masks, start))
        with ThreadPoolExecutor(max_workers=1) as aside:
            grid_job = aside.submit(FloorGrid, work, workspace.bounds,
                                    search=capture_bounds(rig, workspace.bounds))  # not the workspace alone
            silhouettes, start = make_silhouettes(opt, rig, readers if rooms else sources, work)
            grid = grid_job.result()
        for line in getattr(silhouettes, "warnings", []):  # a background clip cut short (.silhouettes)
            warnings.append(line)
            if warn:
                warn(line)
        if rooms:
            readers = {c: reader(r) for c, r in readers.items()}
        total = recording.n_steps - start if recording.n_steps >= 0 else -1
        if recording.n_steps >= 0 and total <= 0:
            raise RecordingError(f"{videos}: no frames left after the {start} background frames")
    except BaseException:
        for r in readers.values():
            r.close()
        raise
    hulls = (PersonHulls(work, ((grid.xs[0], grid.xs[-1]), (grid.ys[0], grid.ys[-1])), workspace.center)
             if ((not opt.masks) if opt.carve is None else opt.carve) else None)
    if opt.max_steps is not None:
        total = opt.max_steps if total < 0 else min(total, opt.max_steps)
    # step 0 is this frame of the cameras without an offset (a negative offset makes them skip frames)
    first_frame = start - min([0] + list(recording.offsets.values()))
    fps = recording.fps
    tracker = tracker_for_fps(fps or 25.0, opt.min_hits, opt.max_misses)
    tracker.look_weight, tracker.max_people = (tracker.look_weight if opt.appearance else 0.0), int(opt.max_people)
    absorb = 0 if opt.masks or opt.absorb_s <= 0 else max(1, int(round(opt.absorb_s * (fps or 25.0))))
    wait = margin_wait(absorb, tracker) if absorb > 0 else 0
    if absorb > 0:  # static clutter becomes background, never a person (module docstring)
        tracker.may_confirm = lambda t: may_be_person(t, grid, wait)
    lag = tracker.decided_within + wait  # a track in the margin is decided after ``wait`` steps: its rows held as long
    cams = {c: CameraStep(readers[c], silhouettes,
                       min_blob_area(rig[names.index(c)], work[names.index(c)], workspace.center, opt.min_area),
                       keep_frame=not opt.masks,
                       cam=work[names.index(c)], absorb_frames=absorb)
            for c, s in sources.items()}
    for c in cams.values():  # colour: each reader thread starts its frames' segmentation (module docstring)
        if isinstance(c.reader, ThreadedReader) and not opt.masks:
            c.reader.after = c.ahead
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {
        "model": model_path, "videos": str(videos), "units": "metres (silpose frame: z up, floor z = 0); "
        "joints_calibration in the calibration's units", "joint_names": list(JOINT_NAMES), "cameras": names,
        "views": modelled, "fps": fps, "first_frame": first_frame, "transform": transform.to_dict(),
        "workspace": workspace.to_dict(), "view_statuses": list(VIEW_STATUSES),
    }
    writer = RecordingWriter(out / "joints.parquet", out / "joints.csv", names, modelled, n_pts, fps, meta,
                             contours=opt.contours)
    overlays = None
    timings = dict.fromkeys(("cameras", "floor", "views", "infer", "place", "write", "overlays"), 0.0)
    camera_status = {c: dict.fromkeys(VIEW_STATUSES, 0) for c in names}
    views_hist = [0] * (len(modelled) + 1)
    floor_tracks: dict[int, list] = {}
    pending: list[tuple[int, PersonRows, list[Track], np.ndarray]] = []
    paths: dict = {}  # track key -> the end of its path among the hypotheses (silpose.model.hypotheses.PathEnd)
    held: ChunkInference | None = None  # the chunk inferred last: decided once the next one is (.chunk_rows)

    def finish_chunk(chunk: ChunkInference, ahead: ChunkInference | None) -> None:
        """Choose ``chunk``'s answers (``ahead``: the next chunk, the choice's look-ahead), place, queue and draw them."""
        t0 = time.perf_counter()
        choose_along_tracks(chunk, ahead, paths)
        timings["infer"] += time.perf_counter() - t0
        rows, world = place_chunk(model, chunk, rig, names, transform, opt, first_frame, timings)
        pending.append((chunk.last_step, rows, [p.track for p in chunk.people],
                        np.array([p.step for p in chunk.people], int)))
        if overlays is not None:
            t0 = time.perf_counter()
            draw_chunk(overlays, rig, work, names, modelled, chunk.step0, chunk.seen, chunk.people, rows, world,
                       first_frame)
            timings["overlays"] += time.perf_counter() - t0
    threads = default_camera_threads(len(cams), threaded) if opt.threads is None else int(opt.threads)
    pool = ThreadPoolExecutor(max_workers=threads) if threads > 0 else None
    cam_list = list(cams.values())
    # mask videos without carving: the view stage in this thread (module docstring, "Threads")
    views_map = pool.map if pool and (not opt.masks or hulls is not None) else map
    # each camera's next step runs ahead while this thread handles the current one (.lookahead): in the pool, or in
    # a pool of its own when the view stage needs the pool meanwhile (colour videos, carving)
    step_pool = ThreadPoolExecutor(max_workers=threads) if pool and views_map is not map else pool
    stepper = StepAhead([c.step for c in cam_list], step_pool, ahead=True)
    for k, c in enumerate(cam_list):  # a background about to learn waits for the camera's step started ahead
        c.quiesce = (lambda k=k: stepper.wait(k)) if stepper.ahead else None
    stale: set[str] = set()  # cameras whose step started ahead was segmented before their background learnt
    step = 0
    detected = 0  # steps with someone on the floor (tracked or not): says why nobody was found
    gone: set[str] = set()  # cameras whose video ended
    blas = threadpool_limits(limits=1, user_api="blas")  # see the module docstring
    cv_threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # the same for OpenCV's own parallel loops (module docstring)
    plan = floorplan_process()  # matplotlib imported beside the run, not at its end (.floorplan_worker)
    try:
        overlays = overlay_sink(opt.overlays, Path(opt.overlay_dir or out / "overlays"), names,
                                {c.name: (c.width, c.height) for c in work}, fps, first_frame,
                                frame_names[start:] if frame_names is not None else None)
        timings["setup"] = time.perf_counter() - t_start
        t_loop_end = None
        done = False
        while not done:
            seen_chunk: list[dict[str, Seen]] = []
            people: list[Person] = []
            while len(seen_chunk) < opt.chunk:
                if total >= 0 and step >= total:
                    done = True
                    break
                t0 = time.perf_counter()
                seen = dict(zip(cams, stepper.next(more=total < 0 or step + 1 < total)))
                for c in stale:  # what the plain loop would have segmented (.lookahead)
                    seen[c] = cams[c].resegment(seen[c])
                stale.clear()
                for c, cam in cams.items():
                    cam.tally(seen[c])
                timings["cameras"] += time.perf_counter() - t0
                ended = [c for c, s in seen.items() if s.status == VIEW_ENDED and c not in gone]
                if ended and frame_names is not None and start + step < len(frame_names):  # a frames folder's contract
                    raise bad_frame(recording.sources[ended[0]], start + step)
                if ended:
                    gone.update(ended)
                    if len(gone) == len(seen):  # no camera left: the recording is over
                        done = True
                        break
                    msg = (f"{', '.join(shown(recording.sources[c]) for c in ended)} ended after {step} frames"
                           + (f" (expected {total})" if total >= 0 else "")
                           + ": a missing view ('video ended') from there on, the other cameras go on")
                    warnings.append(msg)
                    if warn:
                        warn(msg)
                found, where, n_found = step_people(step, seen, rig, work, names, grid, tracker, n_pts, timings,
                                            views_map, hulls,
                                            [cams[c].min_area if c in cams else 1 for c in names], colour=not opt.masks,
                                            explain=absorb > 0)
                people += found
                detected += bool(n_found)
                for c, cam in cams.items():
                    if seen[c].status is None and cam.settle(seen[c], where) and stepper.ahead:
                        stale.add(c)
                seen_chunk.append(seen)
                for c in names:
                    s = seen.get(c)
                    st = VIEW_NO_VIDEO if s is None else (s.status or VIEW_OK)
                    camera_status[c][st] += 1
                step += 1
                if progress:
                    progress(step, total)
            if not seen_chunk:
                break
            inferred = infer_people(model, people, seen_chunk, step - len(seen_chunk), names, modelled, opt, timings)
            if held is not None:  # the chunk before is decided now, this one its look-ahead (.chunk_rows)
                finish_chunk(held, inferred)
            held = inferred
            t0 = time.perf_counter()
            if done and absorb > 0:  # a recording too short to tell: who stood alone in the margin is a person
                tracker.finish(step - 1, lambda t: may_be_person(t, grid))
            pending = emit_rows(pending, writer, step - 1 - lag, views_hist, floor_tracks, final=done)
            timings["write"] += time.perf_counter() - t0
        if held is not None:  # the last chunk, with nothing ahead
            finish_chunk(held, None)
            held = None
        t0 = t_loop_end = time.perf_counter()
        if absorb > 0:  # (as above, when the loop ended on an empty chunk)
            tracker.finish(step - 1, lambda t: may_be_person(t, grid))
        emit_rows(pending, writer, step, views_hist, floor_tracks, final=True)
        writer.close()
        files = [out / "joints.parquet", out / "joints.csv"]
        if overlays is not None:
            files += overlays.close()
            overlays = None
        timings["write"] += time.perf_counter() - t0
    except BaseException:
        writer.abort()
        if overlays is not None:
            overlays.abort()
        if plan is not None:
            plan.kill()
        raise
    finally:
        blas.restore_original_limits()
        cv2.setNumThreads(cv_threads)
        if pool:
            stepper.drain()
            pool.shutdown()
            step_pool.shutdown()
        for c in cams.values():
            c.reader.close()
    for c in cams.values():
        for line in (c.reader.summary(), c.diagnosis(opt.masks)):
            if not line:
                continue
            warnings.append(line)
            if warn:
                warn(line)
    if total >= 0 and step < total:
        warnings.append(f"every camera's video ended after {step} of {total} frames")
        if warn:
            warn(warnings[-1])
    tracks = {p: np.array(v, float).reshape(-1, 3) for p, v in floor_tracks.items()}
    n_persons = len(tracks)
    if n_persons == 0:
        warnings.append(nobody_found(detected, step, tracker.min_hits, fps, opt))
    title = f"{Path(*Path(videos).resolve().parts[-2:])}: {n_persons} person(s), {step} frames"
    if plan is None or not plan.draw(out / "floorplan.png", tracks, rig, title):
        write_floorplan(out / "floorplan.png", tracks, rig, transform, workspace, title)
    files.append(out / "floorplan.png")
    timings["total"] = time.perf_counter() - t_start
    timings["finish"] = time.perf_counter() - t_loop_end
    summary = RecordingSummary(out, files, step, n_persons, dict(writer.counts), views_hist, camera_status, timings, warnings,
                               writer.inside_mean)
    write_json_atomic(out / "summary.json", {
        "frames": step, "persons": n_persons, "rows": writer.counts, "views_hist": views_hist,
        "inside": None if summary.inside != summary.inside else round(summary.inside, 4),
        "camera_status": camera_status, "timings_s": timings, "steps_per_second": summary.steps_per_second,
        "warnings": warnings, "files": [str(p) for p in files],
    })
    summary.files.append(out / "summary.json")
    return summary


def nobody_found(detected: int, steps: int, min_hits: int, fps: float | None, opt: RecordingOptions) -> str:
    """The warning of a run that found nobody, with its cause: nobody on the searched floor in any frame
    (``detected`` = 0; :func:`~.floor.capture_bounds`), or someone on the floor in ``detected`` of ``steps`` frames
    but never ``min_hits`` frames in a row (a track becomes a person after that many, :mod:`.tracking`)."""
    head = "nobody was found on the floor in any frame: joints.parquet has no rows"
    if detected:
        rule = "--min-hits" if opt.min_hits is not None else f"{CONFIRM_S:g} s at {fps or 25.0:g} frames/s"
        return (f"{head}; someone stood on the floor in {detected} of {steps} frames, but a track becomes a person "
                f"after {min_hits} detections in a row ({rule}): for a few moments far apart or a very short clip, "
                "pass --min-hits 1")
    return head + ("; nobody stood on the floor that 2 cameras see"
                   + ("; with --background median, whoever hardly moves over the recording (feet included) is part of "
                      "its background: give empty-room clips (--background DIR)" if str(opt.background) == MEDIAN else ""))


def check_background_options(opt: RecordingOptions, videos, rig) -> None:
    """One-line errors for a recording's mask / background options that contradict each other or are missing."""
    if opt.masks and (opt.background is not None or opt.background_frames is not None):
        raise RecordingError("--masks: mask videos need no background (--background / --background-frames)")
    if not opt.masks and opt.background is not None and opt.background_frames is not None:
        raise RecordingError("give one background: --background DIR or --background-frames N, not both")
    if not opt.masks and opt.background is None and opt.background_frames is None:
        hint = (f" (the camera folders of {videos} hold empty-room clips: --background {videos})"
                if holds_background_clips(Path(videos), rig.names) else "")
        raise RecordingError("colour videos need a background: give --background DIR (empty-room clips) or "
                             "--background-frames N (the first N frames show the empty room), or --masks for mask "
                             f"videos{hint}")


def first_step(opt: RecordingOptions) -> int:
    """The frame index of a run's first step (before offsets): the background frames' count with
    ``--background-frames`` (those frames are not processed), else 0."""
    if opt.masks or opt.background is not None or opt.background_frames is None:
        return 0
    return int(opt.background_frames)


def make_silhouettes(opt: RecordingOptions, rig, sources: dict, work) -> tuple:
    """(the mask maker of :mod:`.silhouettes` the options ask for, the first step's frame index, :func:`first_step`):
    mask videos binarised, or colour videos segmented against empty-room clips, the recording's median or its first
    frames; ``sources`` {camera: CameraSource at the working sizes of ``work`` (cameras in rig order)}, or
    {camera: CameraReader} of those sources when the clips are registered to the recording (``align_plates``;
    :func:`~.silhouettes.room_view` reads its first frames through them)."""
    if opt.masks:
        silhouettes = MaskBinariser()
    elif opt.background is not None and str(opt.background) == MEDIAN and not Path(opt.background).exists():
        silhouettes = background_from_recording(sources, opt.segment_params)
    elif opt.background is not None:
        silhouettes = background_from_clips(Path(opt.background), rig, list(sources), opt.segment_params,
                                            {c.name: (c.width, c.height) for c in work},
                                            sources if opt.align_plates else None)
    else:
        silhouettes = background_from_first_frames(sources, int(opt.background_frames), opt.segment_params)
    return silhouettes, first_step(opt)
