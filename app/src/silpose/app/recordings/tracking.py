"""Stable person ids: floor positions linked over time by optimal assignment, lost tracks re-identified.

Units: positions in metres on the floor (silpose's x, y), time in steps (frames); :func:`tracker_for_fps`
turns the constants below (seconds, metres per second) into steps with the recording's frame rate.

Motion model: a track predicts its position at step ``s`` as ``position + velocity * min(s - last, coast)``
(constant velocity, exponentially smoothed with ``smoothing``, extrapolated at most ``coast`` steps since
people turn and stop). It may take a detection within its gate, which grows with the time it has gone
unseen: ``gate + growth * (s - last - 1)`` metres, at most ``max_gate``.

Appearance (:mod:`.appearance`; on when ``look_weight`` > 0 and the caller passes ``looks``): each person's
track carries a model of their looks per camera (stature and width in metres, for colour videos the colour
histograms of the upper and lower body), learnt by :meth:`Tracker.learn` from the views where they are alone,
only while no other person's track is within ``contact`` metres (a blob then may hold both although the views
call it theirs), slowly, leaving out views far from a settled model.

Per step the detections (D, 2) are linked in three rounds, each an optimal assignment
(``scipy.optimize.linear_sum_assignment``, pairs outside the track's gate forbidden), each on the detections
the rounds before left. The cost of a pair is the floor distance to the track's prediction plus ``look_weight``
times the appearance distance of the detection's views to the track's model (capped per cue; 1 where either is
unknown; asked of the caller only when some track or detection has two feasible partners -- where people
part after a merge -- or a veto may apply); a track that missed a step never takes a
detection whose appearance distance exceeds ``look_gate`` (off by default, :data:`LOOK_GATE`):

1. persons' tracks seen within the last ``recent`` steps (jointly: two people who merged into one detection
   for a frame or two are sorted out together when they part);
2. persons' lost tracks (missed for up to ``max_misses`` steps, a few seconds: through a merge of two
   people into one detection, an occlusion, a segmentation that lost someone): a person who re-emerges
   within reach of where the motion model puts them keeps their id, and that detection starts nothing;
3. tentative tracks.

A detection still left starts a tentative track when the caller allows it (the pipeline lets only
detections whose feet some camera sees start one, :func:`silpose.app.recordings.views.grounded`; only those
count toward a tentative track's hits). A tentative track becomes a person after ``min_hits`` hits -- and, when
the caller sets ``may_confirm``, once that allows it (the pipeline, colour videos: a track that has travelled
:data:`TRAVEL_M` from where it started, :attr:`Track.travel`, or one in the workspace that a camera has seen alone,
or in the margin around it once it has outlived the absorption of static clutter, :meth:`Tracker.finish` when the
recording ends first;
someone who stands still beyond the workspace all along is static clutter that becomes background, not a person;
such a track may become a person later than ``decided_within``, and its rows before that are not written) -- and is
dropped after ``tentative_misses`` consecutive misses (the floor grid's ghosts, between and behind real
people, rarely hold that long; a dropped track leaves no rows). On becoming a person it is first
re-identified: while persons' tracks are lost (last detected before it began, or within ``contact`` of it: one
person's split detection), it takes the id of the one of lowest cost -- distance to its
prediction plus ``look_weight`` times the appearance distance of the two models, none above ``look_gate`` --
within ``reid_gate`` metres and within reach of where it was lost, at ``reid_speed`` (:data:`REID_SPEED_M_S`; that
track ends); else it gets a new public id (1, 2, ... in order). With a head
count (``max_people``) reached, it takes the id of the most alike lost person wherever they were lost, and
while nobody is lost it stays tentative (its rows are not written). A person's track missed for more than
``max_misses`` steps ends; a person coming back after that gets a new id.

Measured on the synthetic lab recording (:data:`silpose.datagen.lab.FOUR_WALKERS`: four walkers of 1.65-1.82 m
crossing, 200 frames at 25 fps, a model trained on 120 lab-rig walkers; ``python -m benchmarks.identities``,
scored by ``benchmarks.recording_scores``; load 7-11 on 2 cores), ids / identity switches with the appearance
model, with motion alone (``look_weight`` 0), and with the tracker before this one: mask videos 4 / 11, 4 / 12,
4 / 12; colour videos (each walker in their own shirt and trousers over a textured room, empty-room clips) 4 /
10 all three; mask videos with walkers hidden from every camera for 1.6-2 s, two at once (``HIDDEN`` of the
benchmark) 4 / 9 all three, and 4 / 9 with ``max_people`` 4. Time steps/s on the masks with and without it
moved with the load (14 vs 26, 22 vs 19, 12 vs 11 in three runs).
The cue is strong where it is seen -- statures from lone views spread 1.3-1.7 cm within a walker, the walkers
are 4-17 cm apart -- but most switches happen where it is not: two or three walkers the floor grid sees as one
detection (a peak between them), where no view shows anyone alone, so a track that follows such a peak, or
jumps to one, has nothing to compare. Tried and dropped: a veto on appearance (``look_gate`` 9: 12 and 11
switches on masks and hidden walkers; 4: 13 and 5 ids -- the models are not clean enough to forbid links, having
learnt from blobs of two walkers the floor grid saw as one), and exchanging two tracks' ids after a contact
when each one's looks since then matched the other's model (no change: 12), and an unknown appearance counted
as 4 instead of 1 (so that a lone view a little off its model is not worse than none: 11 / 10 / 9, the same). Where people part in view,
appearance holds ids that motion alone swaps (two people who turn back inside a merge:
``tests/app/recordings/test_appearance.py``).

History, on an earlier four-walker lab recording (all four 1.91-1.93 m tall; its layout was not kept): the tracker before
lost tracks and re-identification (lost after 0.5 s, 3 hits, smoothing 0.5, a fixed 0.6 m gate) gave 19 ids,
23 identity switches and 72 rows off every true person; with them 4 ids, 10 switches, 11 such rows (625 of 800
person-frames found, 656 before). Offline on the same detections, every one of 18 settings (min_hits 6-10,
smoothing 0.1-0.3, lost 2-4 s) gave 4 ids and 9-12 switches with the 0.3 m gate; with 0.6 m, 14 of 18 gave 4
ids; smoothing 0.5 gave 17-22 switches (the velocity followed the detections' jitter).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import linear_sum_assignment

_FORBIDDEN = 1e6

#: metres: the gate of a track seen at the previous step (the floor grid's jitter and a step's change of pace;
#: 0.6 m let a person's track jump to a ghost between two people who were merging)
GATE_M = 0.3
#: metres per second: the gate's growth while a person is unseen
UNSEEN_SPEED_M_S = 0.5
#: metres a track beyond the workspace must travel from where it started before it becomes a person (module
#: docstring; the pipeline's ``may_confirm``): twice the floor grid's least separation of two people (0.5 m,
#: :meth:`.floor.FloorGrid.locate`) -- a standing person's detection wanders less than that even at the back of the
#: room, where cameras on one wall resolve depth poorly (at most 0.51 m for the three people standing 6.8 m from the
#: lab rig's cameras in tests/app/recordings/test_rooms.py, ``still``) -- so that anyone who walked counts
TRAVEL_M = 1.0
#: seconds a person's lost track waits to be re-identified
LOST_S = 4.0
#: seconds of constant-velocity extrapolation
COAST_S = 0.5
#: seconds of hits a tentative track needs to become a person
CONFIRM_S = 0.3
#: seconds: persons' tracks missed for longer are linked after the others (module docstring, round 2)
RECENT_S = 0.12
#: metres: a new person re-identified to a lost one this near their prediction
REID_GATE_M = 3.0
#: metres per second: a new person is re-identified to a lost one only if a run at this speed (a jog) takes the
#: lost person from where they were last seen to where the new track began, in the time between (plus the contact
#: distance: a track lost in a merge was last seen at the merged detection, between the people): one person is never
#: in two places at once. Without it, on Pose2Sim's two-person demo re-encoded (docs/real-recordings.md), the man's
#: id went to someone standing about 1 m away who appeared within 0.1 s of losing him; with it, two ids, the man's
#: track ending where Pose2Sim's ends. The synthetic lab's ids and switches are unchanged (benchmarks.identities)
REID_SPEED_M_S = 3.0
#: weight of the newest velocity in the smoothed one
SMOOTHING = 0.2
#: metres: a person's appearance model learns only while no other person's track is this near (their blobs
#: may hold both of them although the views call them the person's alone)
CONTACT_M = 0.8
#: metres of assignment cost per unit of appearance distance (:meth:`.appearance.PersonLooks.distance`, ~1 for
#: the same person): the cost of a pair is its floor distance plus this times the distance, capped
LOOK_M = 0.1
#: a track that missed a step never takes a detection, nor a new track a lost person's id, whose appearance
#: distance is above this: off (measured on the lab recording, FOUR_WALKERS, mask videos: 9 gave 12 identity
#: switches and 11 with walkers hidden, 4 gave 13 and 5 ids; off 11 and 9 -- the models are not clean enough
#: to forbid: they learn from blobs holding two walkers that the floor grid sees as one)
LOOK_GATE = float("inf")


@dataclass
class Track:
    """One track. key: internal number; person: public id (0 while tentative); position, velocity: (2,) m and
    m per step; hits: detections so far; misses: consecutive steps without one; last: last detected step;
    first: the step it started; looks: its appearance model (:class:`~.appearance.PersonLooks`,
    :meth:`Tracker.learn`) or None; origin: (2,) m, its first position (None: ``position``); travel: metres, the
    farthest it has been detected from ``origin``; alone: the caller has seen it alone in some camera (the
    pipeline: a usable view of its own, ``VIEW_OK``)."""

    key: int
    position: np.ndarray
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    hits: int = 1
    misses: int = 0
    last: int = 0
    person: int = 0
    first: int = 0
    looks: object = None  # appearance model (the caller's: ``distance(observation) -> float``, NaN unknown)
    origin: np.ndarray | None = None
    travel: float = 0.0
    alone: bool = False

    def __post_init__(self):
        if self.origin is None:
            self.origin = np.array(self.position, float).copy()

    def predict(self, step: int, coast: int = 1 << 30) -> np.ndarray:
        """(2,) metres: where the motion model puts the track at ``step`` (at most ``coast`` steps extrapolated)."""
        return self.position + self.velocity * min(step - self.last, coast)


class Tracker:
    """Assignment tracker (module docstring). gate, max_gate, reid_gate: metres; growth, reid_speed: metres per
    step; max_misses, tentative_misses, min_hits, coast, recent: steps; smoothing in (0, 1]."""

    def __init__(self, gate: float = 0.6, max_misses: int = 12, min_hits: int = 3, smoothing: float = 0.5,
                 growth: float = 0.0, max_gate: float = 2.0, coast: int = 12, tentative_misses: int = 2,
                 reid_gate: float = 0.0, recent: int = 3, contact: float = 0.0, look_weight: float = 0.0,
                 look_gate: float = LOOK_GATE, max_people: int = 0, reid_speed: float = 0.0):
        self.gate, self.max_misses, self.min_hits, self.smoothing = float(gate), int(max_misses), int(min_hits), float(smoothing)
        self.growth, self.max_gate, self.coast = float(growth), float(max_gate), int(coast)
        self.tentative_misses, self.reid_gate, self.recent = int(tentative_misses), float(reid_gate), int(recent)
        self.contact, self.look_weight, self.look_gate = float(contact), float(look_weight), float(look_gate)
        self.max_people = int(max_people)
        self.reid_speed = float(reid_speed)  # metres per step; 0: re-identification bounded by reid_gate alone
        #: tentative track -> may it become a person now (besides ``min_hits``)? None: always (module docstring)
        self.may_confirm: Callable[[Track], bool] | None = None
        self._looks: Callable[[np.ndarray], list] | None = None  # this step's detections' observations
        self._seen: dict[int, object] = {}  # detection -> its observation, this step
        self.tracks: list[Track] = []
        self.n_keys = 0
        self.n_persons = 0
        self.ended: list[Track] = []
        self._reidentified: set[int] = set()  # keys of lost tracks re-identified this step

    @property
    def decided_within(self) -> int:
        """Steps after which a track's public id is known for good: a tentative track is confirmed or dropped
        within ``min_hits * (tentative_misses + 1)`` steps of its start (the pipeline holds rows that long)."""
        return self.min_hits * (self.tentative_misses + 1)

    def _gate(self, t: Track, step: int) -> float:
        return min(self.gate + self.growth * max(step - t.last - 1, 0), max(self.max_gate, self.gate))

    def _observations(self, detections: np.ndarray) -> list:
        """The observations of ``detections`` (I,) (asked of the caller once per detection and step)."""
        ask = [int(d) for d in detections if int(d) not in self._seen]
        if ask and self._looks is not None:
            self._seen.update(zip(ask, self._looks(np.array(ask, int))))
        return [self._seen.get(int(d)) for d in detections]

    def _look_distances(self, tracks: list[Track], cols: np.ndarray, feasible: np.ndarray) -> np.ndarray | None:
        """(T, C) appearance distances of the tracks' models to the detections ``cols`` where ``feasible`` (NaN
        where unknown), or None when they cannot matter: no track has a model, or no track or detection has
        two feasible partners and no veto (``look_gate``) applies to a track that missed a step."""
        if (self.look_weight <= 0 or self._looks is None or not feasible.any()
                or not any(t.looks is not None and t.looks.seen for t in tracks)):
            return None
        contested = feasible.sum(axis=0).max() > 1 or feasible.sum(axis=1).max() > 1
        vetoing = np.isfinite(self.look_gate) and any(t.misses > 0 and feasible[i].any() for i, t in enumerate(tracks))
        if not contested and not vetoing:
            return None
        obs = self._observations(cols)
        out = np.full(feasible.shape, np.nan)
        for i, t in enumerate(tracks):
            if t.looks is None:
                continue
            for j in np.flatnonzero(feasible[i]):
                if obs[j] is not None:
                    out[i, j] = t.looks.distance(obs[j])
        return out

    def _link(self, tracks: list[Track], positions: np.ndarray, free: np.ndarray, step: int) -> dict[int, int]:
        """Optimal assignment of ``tracks`` to the ``free`` (D,) bool detections; {track index: detection}.
        Cost: floor distance + ``look_weight`` x appearance distance (capped; 1 where unknown); a track that
        missed a step is not given a detection whose appearance distance exceeds ``look_gate``."""
        cols = np.flatnonzero(free)
        if not tracks or not len(cols):
            return {}
        pred = np.stack([t.predict(step, self.coast) for t in tracks])
        dist = np.linalg.norm(pred[:, None] - positions[cols][None], axis=2)
        gates = np.array([self._gate(t, step) for t in tracks])
        feasible = dist <= gates[:, None]
        look = self._look_distances(tracks, cols, feasible)
        if look is not None:
            missed = np.array([t.misses > 0 for t in tracks])
            feasible &= ~(missed[:, None] & (look > self.look_gate))  # NaN compares False: unknown is no veto
            dist = dist + self.look_weight * np.where(np.isfinite(look), look, 1.0)
        cost = np.where(feasible, dist, _FORBIDDEN)
        r, c = linear_sum_assignment(cost)
        ok = cost[r, c] < _FORBIDDEN
        return {int(i): int(cols[j]) for i, j in zip(r[ok], c[ok])}

    def update(self, step: int, positions: np.ndarray,
               can_start: np.ndarray | Callable[[np.ndarray], np.ndarray] | None = None,
               looks: Callable[[np.ndarray], list] | None = None) -> list[tuple[Track, int]]:
        """Link the detections ``positions`` (D, 2) of ``step``; returns (track, detection index or -1) for
        every live track (tentative and lost ones included).

        ``can_start``: which detections may start a track or count toward a tentative track's ``min_hits``:
        (D,) bool, or a function of detection indices (I,) -> (I,) bool, asked only about the detections not
        taken by a person's track (so the test costs nothing once everybody is tracked); None: all.
        ``looks``: a function of detection indices (I,) -> I observations (None where unknown) that the tracks'
        ``looks`` models compare (:meth:`~.appearance.PersonLooks.distance`), asked only when an assignment or a
        re-identification has a choice; None: motion alone."""
        positions = np.asarray(positions, float).reshape(-1, 2)
        self._looks, self._seen = looks, {}
        live = self.tracks
        free = np.ones(len(positions), bool)
        assigned = -np.ones(len(live), int)
        recent = [i for i, t in enumerate(live) if t.person and t.misses <= self.recent]
        lost = [i for i, t in enumerate(live) if t.person and t.misses > self.recent]
        tentative = [i for i, t in enumerate(live) if not t.person]
        for group in (recent, lost):
            for i, d in self._link([live[i] for i in group], positions, free, step).items():
                assigned[group[i]] = d
                free[d] = False
        allowed = np.ones(len(positions), bool)
        if can_start is not None:
            ask = np.flatnonzero(free)
            if callable(can_start):
                allowed[ask] = np.asarray(can_start(ask), bool) if len(ask) else allowed[ask]
            else:
                allowed = np.asarray(can_start, bool)
        for i, d in self._link([live[i] for i in tentative], positions, free, step).items():
            assigned[tentative[i]] = d
            free[d] = False
        out: list[tuple[Track, int]] = []
        keep: list[Track] = []
        for t, d in zip(live, assigned):
            if d >= 0:
                dt = step - t.last
                v = (positions[d] - t.position) / max(dt, 1)
                t.velocity = v if t.hits == 1 else self.smoothing * v + (1 - self.smoothing) * t.velocity
                t.position, t.last, t.misses = positions[d].copy(), step, 0
                t.travel = max(t.travel, float(np.linalg.norm(t.position - t.origin)))
                t.hits += 1 if (t.person or allowed[d]) else 0
                if not t.person and t.hits >= self.min_hits and self._confirmable(t):
                    self._confirm(t, keep, step)
            else:
                t.misses += 1
            if t.misses > (self.max_misses if t.person else self.tentative_misses):
                self.ended.append(t)
                continue
            keep.append(t)
            out.append((t, int(d)))
        for d in np.flatnonzero(free & allowed):
            self.n_keys += 1
            t = Track(self.n_keys, positions[d].copy(), last=step, first=step)
            if self.min_hits <= 1 and self._confirmable(t):
                self._confirm(t, keep, step)
            keep.append(t)
            out.append((t, int(d)))
        if self._reidentified:
            keep = [t for t in keep if t.key not in self._reidentified]
            out = [(t, d) for t, d in out if t.key not in self._reidentified]
            self._reidentified.clear()
        self.tracks = keep
        return out

    def finish(self, step: int, may_confirm: Callable[[Track], bool]) -> None:
        """At the end of a recording: the tentative tracks with ``min_hits`` hits that ``may_confirm`` (instead of
        :attr:`may_confirm`) allows become persons (:meth:`_confirm`; in the order they began), for a rule that
        waits longer than the recording lasted. ``step``: the last step (persons detected then are not lost)."""
        for t in sorted((t for t in self.tracks if not t.person and t.hits >= self.min_hits), key=lambda t: t.first):
            if may_confirm(t):
                self._confirm(t, self.tracks, step)
        if self._reidentified:
            self.tracks = [t for t in self.tracks if t.key not in self._reidentified]
            self._reidentified.clear()

    def vouched(self, positions: np.ndarray, step: int) -> np.ndarray:
        """(D,) bool: detections ``positions`` (D, 2) metres of ``step`` within the gate of a person's track seen in
        the last ``recent`` steps, at its prediction -- where the motion model says that person is (the pipeline
        keeps them when it explains the floor grid's ghosts away, :mod:`.ghosts`)."""
        positions = np.asarray(positions, float).reshape(-1, 2)
        tracks = [t for t in self.tracks if t.person and t.misses <= self.recent]
        if not tracks or not len(positions):
            return np.zeros(len(positions), bool)
        pred = np.stack([t.predict(step, self.coast) for t in tracks])
        gates = np.array([self._gate(t, step) for t in tracks])
        return np.any(np.linalg.norm(positions[:, None] - pred[None], axis=2) <= gates[None], axis=1)

    def _confirmable(self, t: Track) -> bool:
        return self.may_confirm is None or bool(self.may_confirm(t))

    def _confirm(self, t: Track, tracks: list[Track], step: int) -> None:
        """Make tentative ``t`` a person: the id of the lost person's track within ``reid_gate`` of lowest cost
        (distance to its prediction + ``look_weight`` times the appearance distance of the two tracks' models;
        which then ends), else a new id. With ``max_people`` ids given out already, the lost track of lowest
        cost whatever its distance (appearance first, distance breaking ties), and while none is lost ``t``
        stays tentative. ``tracks``: the live tracks kept so far this step.

        A person still detected after ``t`` began is ``t`` only if last seen within ``contact`` (``gate`` when 0)
        of ``t``: so near, one blob may hold both and the floor grid split one person in two; farther, they are two
        people, and one person is never in two places at once. (The pipeline writes one row per id and step,
        :func:`~.chunk_rows.one_row_per_person`.)"""
        near = self.contact if self.contact > 0 else self.gate
        lost = [u for u in self.tracks if u.person > 0 and u.last < step and u is not t
                and u.key not in self._reidentified
                and (u.last < t.first or float(np.linalg.norm(u.position - t.position)) <= near)]
        full = 0 < self.max_people <= self.n_persons
        if lost and (self.reid_gate > 0 or full):
            dist = np.array([float(np.linalg.norm(u.predict(step, self.coast) - t.position)) for u in lost])
            a = np.array([self._track_look(u, t) for u in lost])
            look = self.look_weight * np.where(np.isfinite(a), a, 1.0)
            # beyond the head count the motion model has failed (they came back far from where they were lost):
            # the most alike lost person, distance only breaking ties
            cost = look + 1e-3 * dist if full else dist + look
            ok = (np.ones(len(lost), bool) if full else (dist <= self.reid_gate) & self._reachable(lost, t)) \
                & ~(a > self.look_gate)
            if ok.any():
                u = lost[int(np.flatnonzero(ok)[np.argmin(cost[ok])])]
                t.person = u.person
                if u.looks is not None and getattr(u.looks, "seen", False):
                    t.looks = u.looks  # the person's longer memory goes on (the new track's views are few)
                self._reidentified.add(u.key)  # u ends: t goes on as that person
                self.ended.append(u)
                return
        if full:  # every id is someone seen now: t stays tentative (its rows unwritten) until one is lost
            return
        self.n_persons += 1
        t.person = self.n_persons

    def _reachable(self, lost: list[Track], t: Track) -> np.ndarray:
        """(len(lost),) bool: each lost track could have gone from where it was last seen to where ``t`` began, at
        ``reid_speed`` in the steps between, plus ``contact`` (``gate`` when 0: a track lost in a merge was last
        seen at the merged detection, between the people; :data:`REID_SPEED_M_S`); all True without a speed."""
        if self.reid_speed <= 0:
            return np.ones(len(lost), bool)
        gap = np.array([max(t.first - u.last, 0) for u in lost], float)
        far = np.array([float(np.linalg.norm(u.position - t.origin)) for u in lost])
        return far <= (self.contact if self.contact > 0 else self.gate) + self.reid_speed * gap

    def _track_look(self, u: Track, t: Track) -> float:
        """Appearance distance of track ``t``'s model (its means as one observation) to ``u``'s; NaN unknown."""
        if self.look_weight <= 0 or u.looks is None or t.looks is None:
            return float("nan")
        return u.looks.distance(t.looks.views())

    def learn(self, t: Track, step: int, looks: list, new_model: Callable[[], object]) -> None:
        """Let detected track ``t``'s appearance models learn this step's observations ``looks`` (one per
        camera, None where it is not alone in the view) -- only while no other person is near (:meth:`isolated`;
        else their blobs may hold both). ``new_model``: makes an empty model."""
        if self.isolated(t, step):
            t.looks = t.looks or new_model()
            t.looks.update(looks)

    def isolated(self, t: Track, step: int) -> bool:
        """No other person's track (live or lost, at its prediction) within ``contact`` metres of ``t``'s position:
        ``t``'s blobs hold ``t`` alone, its appearance model may learn from them."""
        others = [u.predict(step, self.coast) for u in self.tracks if u is not t and u.person]
        return not others or float(np.min(np.linalg.norm(np.array(others) - t.position, axis=1))) > self.contact


def tracker_for_fps(fps: float, min_hits: int | None = None, max_misses: int | None = None) -> Tracker:
    """The pipeline's tracker for a recording at ``fps`` frames per second (the module's constants, in steps);
    ``min_hits`` / ``max_misses`` (steps) override :data:`CONFIRM_S` / :data:`LOST_S`."""
    fps = float(fps)
    steps = lambda seconds: max(1, int(round(seconds * fps)))  # noqa: E731
    return Tracker(gate=GATE_M, min_hits=steps(CONFIRM_S) if min_hits is None else min_hits,
                   max_misses=steps(LOST_S) if max_misses is None else max_misses, smoothing=SMOOTHING,
                   growth=UNSEEN_SPEED_M_S / fps, coast=steps(COAST_S), reid_gate=REID_GATE_M, recent=steps(RECENT_S),
                   contact=CONTACT_M, look_weight=LOOK_M, reid_speed=REID_SPEED_M_S / fps)
