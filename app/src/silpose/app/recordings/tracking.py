"""Stable person ids: floor positions linked over time by optimal assignment.

Each track predicts its position at the new time step with a constant velocity (exponentially smoothed,
``smoothing``); the detections of the step are assigned to the predictions by the Hungarian algorithm
(``scipy.optimize.linear_sum_assignment``) on the floor distance, pairs farther than ``gate`` metres
apart being forbidden. An unassigned detection starts a tentative track (when the caller allows it: the
pipeline lets only detections whose feet are seen start one, :func:`silpose.app.recordings.views.grounded`,
and only those count toward a tentative track's hits); a track becomes a person (a
public id 1, 2, ... in order of confirmation) once it has ``min_hits`` detections; a track missed for more
than ``max_misses`` consecutive steps ends (a tentative one is dropped: a person who never really
appeared leaves no rows). A person reappearing after their track ended gets a new id.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import linear_sum_assignment

_FORBIDDEN = 1e6


@dataclass
class Track:
    """One track. key: internal number; person: public id (0 while tentative); position, velocity: (2,) m and
    m per step; hits: detections so far; misses: consecutive steps without one; last: last detected step."""

    key: int
    position: np.ndarray
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    hits: int = 1
    misses: int = 0
    last: int = 0
    person: int = 0

    def predict(self, step: int) -> np.ndarray:
        return self.position + self.velocity * (step - self.last)


class Tracker:
    """Assignment tracker (module docstring). gate: metres; max_misses, min_hits: steps; smoothing in (0, 1]."""

    def __init__(self, gate: float = 0.6, max_misses: int = 12, min_hits: int = 3, smoothing: float = 0.5):
        self.gate, self.max_misses, self.min_hits, self.smoothing = float(gate), int(max_misses), int(min_hits), float(smoothing)
        self.tracks: list[Track] = []
        self.n_keys = 0
        self.n_persons = 0
        self.ended: list[Track] = []

    def update(self, step: int, positions: np.ndarray,
               can_start: np.ndarray | Callable[[np.ndarray], np.ndarray] | None = None) -> list[tuple[Track, int]]:
        """Link the detections ``positions`` (D, 2) of ``step``; returns (track, detection index or -1) for
        every live track (tentative ones included).

        ``can_start``: which detections may start a track or count toward a tentative track's ``min_hits``:
        (D,) bool, or a function of detection indices (I,) -> (I,) bool, asked only about the detections not
        taken by a person's track (so the test costs nothing once everybody is tracked); None: all."""
        positions = np.asarray(positions, float).reshape(-1, 2)
        live = self.tracks
        assigned = -np.ones(len(live), int)
        if live and len(positions):
            pred = np.stack([t.predict(step) for t in live])
            cost = np.linalg.norm(pred[:, None] - positions[None], axis=2)
            cost = np.where(cost > self.gate, _FORBIDDEN, cost)
            rows, cols = linear_sum_assignment(cost)
            ok = cost[rows, cols] < _FORBIDDEN
            assigned[rows[ok]] = cols[ok]
        used = set(assigned[assigned >= 0].tolist())
        allowed = np.ones(len(positions), bool)
        if can_start is not None:
            ask = np.array(sorted(set(range(len(positions))) - {int(d) for t, d in zip(live, assigned) if t.person and d >= 0}),
                           int)
            if callable(can_start):
                allowed[ask] = np.asarray(can_start(ask), bool) if len(ask) else allowed[ask]
            else:
                allowed = np.asarray(can_start, bool)
        out: list[tuple[Track, int]] = []
        keep: list[Track] = []
        for t, d in zip(live, assigned):
            if d >= 0:
                dt = step - t.last
                v = (positions[d] - t.position) / max(dt, 1)
                t.velocity = v if t.hits == 1 else self.smoothing * v + (1 - self.smoothing) * t.velocity
                t.position, t.last, t.misses = positions[d].copy(), step, 0
                t.hits += 1 if (t.person or allowed[d]) else 0
                if not t.person and t.hits >= self.min_hits:
                    self.n_persons += 1
                    t.person = self.n_persons
            else:
                t.misses += 1
            if t.misses > self.max_misses:
                self.ended.append(t)
                continue
            keep.append(t)
            out.append((t, int(d)))
        for d in range(len(positions)):
            if d not in used and allowed[d]:
                self.n_keys += 1
                t = Track(self.n_keys, positions[d].copy(), last=step)
                if self.min_hits <= 1:
                    self.n_persons += 1
                    t.person = self.n_persons
                keep.append(t)
                out.append((t, d))
        self.tracks = keep
        return out
