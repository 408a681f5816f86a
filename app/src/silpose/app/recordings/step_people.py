"""One time step's people (:mod:`.pipeline`): floor detection, tracking, the people's visual hulls, and each
camera's view of each person."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import cv2
import numpy as np

from .appearance import PersonLooks, observe
from .blobs import blob_contour, find_blobs
from .camera_step import Seen
from .floor import MARGIN_M, FloorGrid
from .ghosts import explain_away
from .hull import PersonHulls
from .resolution import to_rig_px
from .tracking import TRAVEL_M, Track, Tracker
from .views import VIEW_EMPTY, VIEW_NO_VIDEO, VIEW_NOT_SEEN, VIEW_OK, assign_views, grounded, person_labels

#: metres: floor detections this close to the floor grid's outer edge are not people in the room but someone
#: beyond it (people standing at the back: the rays through them cross the grid's last cells)
EDGE_M = 0.15


@dataclass
class Person:
    """A person (track) at one step, before inference."""

    step: int
    track: Track
    floor: np.ndarray  # (2,) or NaN
    status: list  # (K,) view statuses
    contours: np.ndarray  # (K, n, 2) px, NaN where not used
    cut: np.ndarray  # (K,) share of the person's blob cut as unsupported by the other views (.hull), NaN: no blob


def camera_views(cam, work, s: Seen | None, positions: np.ndarray, n_pts: int,
                 support: Callable[[], np.ndarray] | None = None, min_area: int = 1,
                 colour: bool = False) -> tuple[list, np.ndarray, np.ndarray, list]:
    """One camera's view of the P detected people: (statuses (P,), contours (P, n, 2) in ``cam``'s px, NaN
    where unused, cut shares (P,), looks (P,) :class:`~.appearance.Look` or None), from the masks at ``work``'s
    resolution. ``support``: makes the camera's visual-hull support image (:meth:`.hull.PersonHulls.support`),
    which the mask is cut down to before its blobs (of at least ``min_area`` px) are judged; the cut share is the
    part of the person's blob it removed (NaN: no blob). ``colour``: colour histograms from the frame. Runs in a
    worker thread (OpenCV's labelling and contour tracing release the GIL)."""
    P = len(positions)
    cont = np.full((P, n_pts, 2), np.nan)
    cut = np.full(P, np.nan)
    looks: list = [None] * P
    if s is None:
        return [VIEW_NO_VIDEO] * P, cont, cut, looks
    if s.blobs is None or s.blobs.empty:
        return [s.status or VIEW_EMPTY] * P, cont, cut, looks
    blobs = s.blobs
    if support is not None and P:
        before = person_labels(work, blobs, positions)
        blobs = find_blobs(cv2.bitwise_and(s.mask, support()), min_area)
        after = person_labels(work, blobs, positions)
        has = before > 0
        cut[has] = 1.0 - blobs.area[after[has]] * (after[has] > 0) / s.blobs.area[before[has]]
        if blobs.empty:
            return [VIEW_NOT_SEEN] * P, cont, cut, looks
    labels, status = assign_views(work, blobs, positions)
    for d in range(P):
        if status[d] == VIEW_OK:
            pts = blob_contour(blobs, labels[d], n_pts)
            if pts is None:
                status[d] = VIEW_EMPTY
            else:
                cont[d] = to_rig_px(pts, cam, work)
                looks[d] = observe(work, blobs, labels[d], positions[d], s.background if colour else None)
    return status, cont, cut, looks


def detection_looks(work, seen: list, positions: np.ndarray, colour: bool, mapper=map) -> Callable:
    """The tracker's ``looks``: detection indices (I,) -> I lists of per-camera :class:`~.appearance.Look`
    (None where the detection is not alone in that view: every camera's views of all ``positions`` (D, 2)
    assigned at once, when first asked, so a blob two detections share is nobody's)."""
    cache: list = []

    def one_camera(k: int) -> list:
        s = seen[k]
        if s is None or s.blobs is None or s.blobs.empty:
            return [None] * len(positions)
        labels, status = assign_views(work[k], s.blobs, positions)
        return [observe(work[k], s.blobs, labels[d], positions[d], s.background if colour else None)
                if status[d] == VIEW_OK else None for d in range(len(positions))]

    def looks(idx: np.ndarray) -> list:
        if not cache:
            per_cam = list(mapper(one_camera, range(len(work))))
            cache.append([[per_cam[k][d] for k in range(len(work))] for d in range(len(positions))])
        return [cache[0][int(d)] for d in idx]

    return looks


def step_people(step, seen: dict, rig, work, names, grid: FloorGrid, tracker: Tracker, n_pts: int, timings,
                mapper=map, hulls: PersonHulls | None = None, min_areas=None,
                colour: bool = False, explain: bool = False) -> tuple[list[Person], np.ndarray, int]:
    """Floor detection, tracking, the people's visual hulls (``hulls``, :mod:`.hull`; None: views uncut) and
    (per camera, through ``mapper``) view assignment of one step; ``min_areas`` (K,) px: blobs of the cut masks;
    ``colour``: the people's looks include colour histograms (:mod:`.appearance`); ``explain``: explain the grid's
    ghosts away (:mod:`.ghosts`; the pipeline: where static clutter becomes background, colour videos).

    Only detections whose feet some camera sees may start a
    track (:func:`~.views.grounded`); detections no track takes, and static clutter's tracks (:func:`static_clutter`),
    are dropped before the views are assigned, so neither makes a real person's blob look shared. Returns the
    step's people, the floor points (P, 2) of the persons whose boxes are protected from becoming background
    (``CameraStep.settle``) and the number of detections."""
    t0 = time.perf_counter()
    masks, blobs = [], []
    for c in names:
        s = seen.get(c)
        ok = s is not None and s.blobs is not None and not s.blobs.empty
        masks.append(s.mask if ok else None)
        blobs.append(s.blobs if ok else None)
    det = grid.locate(masks)
    if len(det.positions):  # a peak on the search area's edge is someone beyond it (their hull reaches in)
        xy = det.positions
        inner = ((xy[:, 0] > grid.xs[0] + EDGE_M) & (xy[:, 0] < grid.xs[-1] - EDGE_M)
                 & (xy[:, 1] > grid.ys[0] + EDGE_M) & (xy[:, 1] < grid.ys[-1] - EDGE_M))
        det = type(det)(det.positions[inner], det.scores[inner])
    seen_by = [k for k, b in enumerate(blobs) if b is not None]
    feet = np.full(len(det.positions), -1)  # cameras in which each detection's blob ends at its feet (-1: not asked)

    def count_feet(idx: np.ndarray) -> np.ndarray:
        ask = idx[feet[idx] < 0]
        if len(ask):
            xy = det.positions[ask]
            feet[ask] = (np.sum(list(mapper(lambda k: grounded(work[k], blobs[k], xy), seen_by)), axis=0) if seen_by
                         else 0)
        return feet[idx]

    if explain and len(det.positions) > 1 and seen_by:  # ghosts explained away by the people found first (.ghosts)
        # strongest first: where a person seen lately is predicted (within their gate: that person, kept), then
        # grounded in more cameras (asked only when several others compete), then score
        tracked = tracker.vouched(det.positions, step)
        need = np.where(tracked, 0, grid.min_views)
        if (~tracked).sum() > 1:
            count_feet(np.flatnonzero(~tracked))
        order = np.lexsort((-det.scores, -np.maximum(feet, 0), ~tracked))
        keep = explain_away(work, masks, det.positions, order, need)
        det, feet = type(det)(det.positions[keep], det.scores[keep]), feet[keep]

    def feet_seen(idx: np.ndarray) -> np.ndarray:  # asked only about detections no person's track took
        return count_feet(np.asarray(idx, int)) > 0

    looks = detection_looks(work, [seen.get(c) for c in names], det.positions, colour, mapper)
    links = tracker.update(step, det.positions, feet_seen, looks if tracker.look_weight > 0 else None)
    timings["floor"] += time.perf_counter() - t0
    t0 = time.perf_counter()
    # static clutter's tracks (colour videos: tracker.may_confirm) take no views (a blob it shares with a person is
    # the person's) and protect nothing
    clutter = (lambda t: static_clutter(t, grid)) if tracker.may_confirm is not None else (lambda t: False)
    taken = [d for t, d in links if d >= 0 and not clutter(t)]
    where = det.positions[taken]
    # persons protect their boxes from becoming background (CameraStep.settle); tentative tracks and ghosts do not
    near = det.positions[[d for t, d in links if d >= 0 and t.person]].reshape(-1, 2)
    kept = boxes = None
    if hulls is not None and len(where):
        boxes = hulls.prepare(where)  # and the tiles the threads read
        # in this thread: a dilation of the people's pixels per camera is less than a pool round trip under load
        live = [hulls.evidence(k, masks[k], boxes) for k in range(len(names))]
        if sum(live) >= 2:  # one camera alone supports nothing
            kept = hulls.keep(live, boxes)

    def views(k: int):
        sup = None
        if kept is not None and masks[k] is not None:
            sup = lambda: hulls.support(k, kept, boxes, masks[k].shape)  # noqa: E731
        return camera_views(rig[k], work[k], seen.get(names[k]), where, n_pts, sup,
                             1 if min_areas is None else int(min_areas[k]), colour)

    per_cam = list(mapper(views, range(len(names))))
    out = []
    for track, d in links:
        if d < 0 or d not in taken:
            out.append(Person(step, track, np.full(2, np.nan) if d < 0 else det.positions[d].copy(),
                               [VIEW_NOT_SEEN] * len(names), np.full((len(names), n_pts, 2), np.nan),
                               np.full(len(names), np.nan)))
        else:
            i = taken.index(d)
            if tracker.look_weight > 0 or tracker.max_people > 0:  # the person's appearance model learns
                tracker.learn(track, step, [lk[i] for _, _, _, lk in per_cam], lambda: PersonLooks(len(names)))
            track.alone = track.alone or any(st[i] == VIEW_OK for st, _, _, _ in per_cam)
            out.append(Person(step, track, det.positions[d].copy(), [st[i] for st, _, _, _ in per_cam],
                               np.stack([c[i] for _, c, _, _ in per_cam]), np.array([u[i] for _, _, u, _ in per_cam])))
    timings["views"] += time.perf_counter() - t0
    return out, near, len(det.positions)


def static_clutter(track: Track, grid: FloorGrid) -> bool:
    """A tentative track beyond the workspace and the margin the floor grid searches around it (:data:`.floor.MARGIN_M`)
    that has not walked (:data:`~.tracking.TRAVEL_M`): someone or something standing there, which becomes background
    (module docstring, "Static clutter"). Within the margin a person standing still is a person: an imported
    workspace can be small (Pose2Sim's demo: 1.5 m x 0.7 m, its two people up to 0.4 m outside it)."""
    return not track.person and track.travel < TRAVEL_M and not bool(grid.in_workspace(track.position, MARGIN_M)[0])


def may_be_person(track: Track, grid: FloorGrid, wait: int = 0) -> bool:
    """The tracker's ``may_confirm``: a track becomes a person once it has walked :data:`~.tracking.TRAVEL_M`, or once
    some camera has seen it alone (a usable view of its own; the floor grid's ghosts, which live on other people's
    blobs, never have one) -- in the workspace at once, in the margin around it (:data:`.floor.MARGIN_M`) only when
    it has been tracked for ``wait`` steps (:func:`margin_wait`: it outlived the absorption of static clutter, so it
    moves) or when the recording ends before that (:meth:`~.tracking.Tracker.finish`: too short to tell)."""
    if track.travel >= TRAVEL_M:
        return True
    if not track.alone:
        return False
    if bool(grid.in_workspace(track.position)[0]):
        return True
    return bool(grid.in_workspace(track.position, MARGIN_M)[0]) and track.last - track.first >= wait


def margin_wait(absorb: int, tracker: Tracker) -> int:
    """Steps a track in the workspace's margin waits before it may become a person (:func:`may_be_person`): the
    ``absorb`` steps after which static clutter becomes background, then the steps a tentative track lasts unseen
    and the hits it needs (a track that still stands there was not absorbed: someone moving, not clutter)."""
    return int(absorb) + tracker.decided_within
