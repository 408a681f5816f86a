"""A chunk of time steps' people (:mod:`.pipeline`) turned into rows: inference (:func:`infer_people`); the answer
chosen along each track once the next chunk is inferred (:func:`choose_along_tracks`); placement in the room and the
silhouette fit (:func:`place_chunk`); rows written one per person and step once their tracks are decided
(:func:`emit_rows`); overlays drawn (:func:`draw_chunk`)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from silpose.model.hypotheses import Hypotheses, continue_choice, sequence_answer
from silpose.model.result import InferenceResult
from silpose.shared.skeleton import N_JOINTS

from ..inference import InferOptions, hypotheses_kept, infer_rows
from .overlay_png import OverlayPngs, draws_overlays
from .overlay_video import OverlayVideos
from .placement import place_contours, place_roots
from .silhouette_fit import fit_to_silhouettes, share_inside
from .resolution import to_work_px
from .views import VIEW_NOT_MODELLED, VIEW_OK
from .step_people import Person
from .writers import STATUS_IMPLAUSIBLE, STATUS_NO_VIEW, STATUS_NOT_DETECTED, STATUS_OK, PersonRows, RecordingWriter


@dataclass
class ChunkInference:
    """A chunk's people inferred (:func:`infer_people`), before each row's answer is chosen along its track and placed
    (:func:`place_chunk`). The pipeline holds it until the next chunk is inferred: that chunk is the choice's
    look-ahead (:func:`choose_along_tracks`).

    Attributes:
        people: the chunk's R people (rows), in step order; seen: the chunk's camera frames, one dict per step (for the
            overlays); step0: the chunk's first step.
        view_status: (R, K) per rig camera; used: (R, K) bool, the views inferred from; detected: (R,) bool.
        rows: (R_inf,) the people inferred (detected, with a usable view); contours: (R_inf, K, n, 2) px, theirs;
        result: their :class:`~silpose.model.result.InferenceResult` (None without rows).
    """

    people: list[Person]
    seen: list
    step0: int
    view_status: np.ndarray
    used: np.ndarray
    detected: np.ndarray
    rows: np.ndarray
    contours: np.ndarray | None = None
    result: InferenceResult | None = None

    @property
    def hypotheses(self) -> Hypotheses | None:
        return None if self.result is None else self.result.hypotheses

    @property
    def keys(self) -> np.ndarray:
        """(R_inf,) the inferred rows' track keys."""
        return np.array([self.people[i].track.key for i in self.rows])

    @property
    def steps(self) -> np.ndarray:
        """(R_inf,) int, the inferred rows' time steps."""
        return np.array([self.people[i].step for i in self.rows], np.int64)

    @property
    def last_step(self) -> int:
        return self.step0 + len(self.seen) - 1


def infer_people(model, people: list[Person], seen: list, step0: int, names, modelled, opt, timings) -> ChunkInference:
    """The model's inference of a chunk's people from their usable modelled views (``opt``: the run's
    :class:`~.pipeline.RecordingOptions`; at least :data:`~silpose.model.hypotheses.TEMPORAL_HYPOTHESES` hypotheses
    kept when ``opt.hypotheses``)."""
    R, K = len(people), len(names)
    view_status = np.array([p.status for p in people], dtype=object).reshape(R, K)
    is_modelled = np.array([c in modelled for c in names])
    view_status[:, ~is_modelled] = np.where(view_status[:, ~is_modelled] == VIEW_OK, VIEW_NOT_MODELLED,
                                            view_status[:, ~is_modelled])
    used = view_status == VIEW_OK
    detected = np.array([np.all(np.isfinite(p.floor)) for p in people], bool)
    chunk = ChunkInference(people, seen, step0, view_status, used, detected, np.flatnonzero(detected & used.any(axis=1)))
    if len(chunk.rows):
        t0 = time.perf_counter()
        chunk.contours = np.stack([people[i].contours for i in chunk.rows])
        # untangled (simple) contours only matter where they are drawn or written (~0.2 ms a contour, batched)
        robust = (not opt.masks) if opt.robust is None else bool(opt.robust)
        options = InferOptions(noise_variance=opt.noise_variance, hypotheses=hypotheses_kept(opt.hypotheses, True),
                               robust=robust, untangle=draws_overlays(opt.overlays) or opt.contours)
        chunk.result = infer_rows(model, chunk.contours, used[chunk.rows], options=options)
        timings["infer"] += time.perf_counter() - t0
    return chunk


def choose_along_tracks(chunk: ChunkInference, ahead: ChunkInference | None, paths: dict) -> None:
    """Set the chosen hypothesis of every inferred row of ``chunk`` (in place): per track, the slots on these rows of the
    path over the track's frames so far and ``ahead``'s (the next chunk, None at the end) that is best at the last of
    them (:func:`silpose.model.hypotheses.continue_choice`, as a whole sequence is chosen). ``paths``: track key ->
    the end of its path after its rows already chosen, moved past ``chunk``'s (in place). Every row is decided with at
    least the next chunk's frames ahead: the rows are written no earlier than that anyway (the tracks' ids,
    :func:`emit_rows`)."""
    hyp = chunk.hypotheses
    if hyp is None:
        return
    keys, steps = chunk.keys, chunk.steps
    a_hyp = None if ahead is None else ahead.hypotheses
    a_keys = ahead.keys if a_hyp is not None else np.zeros(0, keys.dtype)
    for key in dict.fromkeys(keys.tolist()):
        mine = np.flatnonzero(keys == key)
        start = paths.get(key)
        own = hyp.take(mine)
        chosen, paths[key] = continue_choice(own, steps[mine], start)
        later = np.flatnonzero(a_keys == key)
        if len(later):  # the path best at the end of the look-ahead, on this chunk's rows
            joined = Hypotheses.concat([own, a_hyp.take(later)])
            slots, _ = continue_choice(joined, np.r_[steps[mine], ahead.steps[later]], start)
            chosen = slots[:len(mine)]
        hyp.chosen[mine] = chosen


def place_chunk(model, chunk: ChunkInference, rig, names, transform, opt, first_frame, timings):
    """PersonRows of the chunk's people (person ids filled in at emission), and world joints (R, 19, 3): each inferred
    row's answer (its chosen hypothesis, :func:`choose_along_tracks`; the posterior mean without hypotheses) with the
    root placed in the room, and fitted inside the silhouettes with ``opt.silhouette_fit``."""
    people, rows, used = chunk.people, chunk.rows, chunk.used
    R, K = len(people), len(names)
    lay = model.fitted_layout()
    V, n_pts = len(lay.views), lay.n_points
    nan = lambda *s: np.full((R,) + s, np.nan)  # noqa: E731
    joints, std, root = nan(N_JOINTS, 3), nan(N_JOINTS, 3), nan(3)
    contours, logm, plaus, hyp_p, inside = nan(V, n_pts, 2), nan(), nan(), nan(), nan()
    hyp_slot = np.zeros(R, np.int8)
    status = np.array([STATUS_NOT_DETECTED] * R, dtype=object)
    status[chunk.detected] = STATUS_NO_VIEW
    res = chunk.result
    if res is not None:
        t0 = time.perf_counter()
        c = chunk.contours
        pose = sequence_answer(res.joints, res.hypotheses)
        if res.hypotheses is not None:
            hyp = res.hypotheses
            hyp_slot[rows] = hyp.chosen + 1
            hyp_p[rows] = hyp.probability[np.arange(len(rows)), hyp.chosen]
        cams = [rig[v] for v in res.views]
        floor = np.stack([people[i].floor for i in rows])
        r = place_roots(pose, res.centroid, res.views_present, cams, floor)
        joints[rows] = pose + r[:, None]
        if opt.silhouette_fit:  # each joint moved inside the outlines of the views used (.silhouette_fit)
            joints[rows] = fit_to_silhouettes(joints[rows], res.joint_std, c, used[rows], list(rig))
            r = joints[rows, 0].copy()  # the root is the pelvis joint
        inside[rows] = share_inside(joints[rows], c, used[rows], list(rig))
        std[rows] = res.joint_std
        root[rows] = r
        contours[rows] = place_contours(res, r, cams)
        logm[rows] = res.log_marginal
        if res.plausibility is not None:
            plaus[rows] = res.plausibility
        implausible = np.zeros(len(rows), bool) if res.implausible is None else np.asarray(res.implausible, bool)
        status[rows] = np.where(implausible, STATUS_IMPLAUSIBLE, STATUS_OK)
        timings["place"] += time.perf_counter() - t0
    floor = np.stack([p.floor for p in people]) if R else np.zeros((0, 2))
    rows_out = PersonRows(
        frame=np.array([p.step for p in people], np.int64) + first_frame, person=np.zeros(R, np.int32),
        status=status, floor=floor, view_status=chunk.view_status, views_used=used,
        view_cut=np.stack([p.cut for p in people]) if R else np.zeros((0, K)), log_marginal=logm,
        plausibility=plaus, hypothesis=hyp_slot, hypothesis_probability=hyp_p, joints=joints,
        joints_calibration=transform.to_calibration(joints), joint_std=std, root=root,
        root_calibration=transform.to_calibration(root), contours=contours, inside=inside)
    return rows_out, joints


def one_row_per_person(steps: np.ndarray, person: np.ndarray, began: np.ndarray) -> np.ndarray:
    """(R,) bool: the rows to write of rows at ``steps`` (R,) of ``person`` ids (R,; 0: not a person), one per id
    and step: where two tracks hold one id at one step (a track re-identified as a person whose split detection
    it was, :meth:`~.tracking.Tracker.update`), the row of the track that began first (``began``, (R,) steps)."""
    keep = np.asarray(person) > 0
    if len(keep) < 2:
        return keep
    order = np.lexsort((began, person, steps))  # by step, then id, then the older track first
    s, p = steps[order], person[order]
    repeat = np.r_[False, (s[1:] == s[:-1]) & (p[1:] == p[:-1])]
    keep[order[repeat]] = False
    return keep


def emit_rows(pending, writer: RecordingWriter, cutoff: int, views_hist, floor_tracks, final: bool):
    """Write the held-back chunks whose steps are all <= ``cutoff`` (all of them when ``final``): rows of
    tracks that became persons, minus not-detected rows after a track's last detection, one per id and step
    (:func:`one_row_per_person`). Returns the rest."""
    keep = []
    for last, rows, tracks, steps in pending:
        if not final and last > cutoff:
            keep.append((last, rows, tracks, steps))
            continue
        person = np.array([t.person for t in tracks], np.int32)
        bridged = np.array([t.last > s for t, s in zip(tracks, steps)], bool)  # detected again after this step
        ok = (person > 0) & ((rows.status != STATUS_NOT_DETECTED) | bridged)
        ok &= one_row_per_person(steps, np.where(ok, person, 0), np.array([t.first for t in tracks], int))
        if not ok.any():
            continue
        out = rows.take(np.flatnonzero(ok))
        out.person = person[ok]
        writer.write(out)
        for i in np.flatnonzero(out.status != STATUS_NOT_DETECTED):
            views_hist[int(out.views_used[i].sum())] += 1
            xy = out.root[i, :2] if np.all(np.isfinite(out.root[i])) else out.floor[i]
            floor_tracks.setdefault(int(out.person[i]), []).append((out.frame[i], xy[0], xy[1]))
    return keep


def draw_chunk(overlays: "OverlayVideos | OverlayPngs", rig, work, names, modelled, step0: int, seen_chunk, people, rows: PersonRows,
               world, first_frame: int) -> None:
    """Overlay frames of the chunk's steps (module :mod:`.overlay_video`), at the cameras' working size."""
    by_step: dict[int, list[int]] = {}
    for i, p in enumerate(people):
        if np.all(np.isfinite(p.floor)):
            by_step.setdefault(p.step, []).append(i)
    # every camera's projections of the chunk's joints and column tops at once (one call per camera, not per item)
    has_joints = np.all(np.isfinite(world.reshape(len(world), -1)), axis=1) if len(world) else np.zeros(0, bool)
    tops = np.array([[p.floor[0], p.floor[1], 2.0] for p in people]).reshape(-1, 3)
    joints_px = [w.project(world[has_joints].reshape(-1, 3)).reshape(-1, N_JOINTS, 2) for w in work]
    tops_px = [w.project(tops) if len(tops) else np.zeros((0, 2)) for w in work]
    slot = np.cumsum(has_joints) - 1  # row -> its index among the rows with joints
    for j, seen in enumerate(seen_chunk):
        step = step0 + j
        idx = by_step.get(step, [])
        for k, c in enumerate(names):
            cam, wcam = rig[k], work[k]
            s = seen.get(c)
            items = []
            for i in idx:
                p = people[i]
                outline = to_work_px(p.contours[k], cam, wcam) if np.all(np.isfinite(p.contours[k])) else None
                recon = to_work_px(rows.contours[i, modelled.index(c)], cam, wcam) if c in modelled else None
                jp = joints_px[k][slot[i]] if has_joints[i] else None
                items.append({"person": p.track.person, "status": rows.view_status[i, k], "outline": outline,
                              "recon": recon, "joints_px": jp, "anchor_px": tops_px[k][i]})
            overlays.draw(c, None if s is None else s.background, (wcam.width, wcam.height), step + first_frame, items)
