"""Explaining away the floor grid's ghosts (silpose.app.recordings.ghosts) and the static-clutter rules of the
pipeline (a person beyond the workspace must have walked)."""

from __future__ import annotations

import numpy as np

from silpose.app.recordings.blobs import find_blobs
from silpose.app.recordings.floor import FloorGrid
from silpose.app.recordings.ghosts import explain_away
from silpose.app.recordings.step_people import may_be_person, static_clutter
from silpose.app.recordings.tracking import TRAVEL_M, Track, Tracker
from silpose.app.recordings.views import grounded
from silpose.shared.rig_frame import DEFAULT_WORKSPACE

#: two people whose rays cross 0.6 m behind the second one (cameras on one wall): the grid finds a ghost there
PEOPLE = np.array([[-0.5, -0.5], [0.5, 0.8]])


def _scene(rig, tools):
    masks = [(m > 0).view(np.uint8) for m in tools.cylinder_masks(rig, PEOPLE)]
    det = FloorGrid(list(rig), DEFAULT_WORKSPACE.bounds).locate(masks)
    near = np.linalg.norm(det.positions[:, None] - PEOPLE[None], axis=2).min(axis=1) < 0.1
    return masks, det, near


def test_the_people_found_first_explain_the_ghost_away(rig, tools):
    masks, det, real = _scene(rig, tools)
    assert real.sum() == 2 and (~real).sum() >= 1  # the grid alone: both people and a ghost (scored as high)
    assert det.scores[~real].max() >= det.scores[real].min()
    # the pipeline's order: the candidates whose blob ends at their own feet in more cameras first (views.grounded)
    feet = np.sum([grounded(cam, find_blobs(m, 50), det.positions) for cam, m in zip(rig, masks)], axis=0)
    assert feet[real].min() > feet[~real].max()
    keep = explain_away(list(rig), masks, det.positions, np.lexsort((-det.scores, -feet)))
    assert keep.tolist() == real.tolist()
    # the order matters: the ghost taken first is kept and explains a real person away
    ghost_first = np.r_[np.flatnonzero(~real), np.flatnonzero(real)]
    wrong = explain_away(list(rig), masks, det.positions, ghost_first)
    assert wrong[~real].all() and wrong[real].sum() == 1


def test_explain_away_keeps_a_lone_person_and_drops_a_candidate_on_no_foreground(rig, tools):
    masks = [(m > 0).view(np.uint8) for m in tools.cylinder_masks(rig, PEOPLE[:1])]
    xy = np.array([PEOPLE[0], [1.0, 1.0]])  # a person, and a floor point where nothing stands
    assert explain_away(list(rig), masks, xy, [1, 0]).tolist() == [True, False]
    # a camera without a mask says nothing: three cameras are still two
    assert explain_away(list(rig), [None] + masks[1:], xy, [0, 1]).tolist() == [True, False]
    # seen by one camera only: not kept with min_views 2, kept where the caller asks one camera of that candidate
    assert explain_away(list(rig), [masks[0], None, None, None], xy, [0, 1]).tolist() == [False, False]
    assert explain_away(list(rig), [masks[0], None, None, None], xy, [0, 1], min_views=[1, 1]).tolist() == [True, False]
    assert explain_away(list(rig), masks, np.zeros((0, 2)), []).tolist() == []


def test_a_track_beyond_the_workspace_becomes_a_person_only_after_walking(rig):
    grid = FloorGrid(list(rig), DEFAULT_WORKSPACE.bounds)
    (_, _), (_, y1) = grid.workspace
    tr = Tracker(min_hits=2)
    tr.may_confirm = lambda t: may_be_person(t, grid)
    back = np.array([[0.0, y1 + 0.6]])  # someone standing beyond the workspace, seen alone
    for step in range(6):
        links = tr.update(step, back + [0.05 * (step % 2), 0.0])
        for t, _ in links:
            t.alone = True
    (t, _), = links
    assert tr.n_persons == 0 and static_clutter(t, grid) and t.travel < TRAVEL_M
    for step in range(6, 6 + 8):  # they walk towards the cameras, 0.25 m a step
        (t, _), = tr.update(step, back - [0.0, 0.25 * (step - 5)])
        if t.travel >= TRAVEL_M:
            break
    assert t.person == 1 and not static_clutter(t, grid) and t.travel >= TRAVEL_M
    # in the workspace, standing still: a person once some camera saw them alone, not before
    inside = Track(1, np.array([0.2, 0.1]))
    assert not may_be_person(inside, grid) and not static_clutter(inside, grid)
    inside.alone = True
    assert may_be_person(inside, grid)
    assert grid.in_workspace(np.array([[0.0, 0.0], [0.0, y1 + 0.1]])).tolist() == [True, False]
    # in the margin around the workspace, seen alone: a person only once tracked for ``wait`` steps
    beside = Track(2, np.array([0.0, y1 + 0.3]), first=10, last=10, alone=True)
    assert not static_clutter(beside, grid)
    assert may_be_person(beside, grid) and not may_be_person(beside, grid, wait=5)
    beside.last = 14
    assert not may_be_person(beside, grid, wait=5)
    beside.last = 15
    assert may_be_person(beside, grid, wait=5)
    inside.first, inside.last = 10, 10
    assert may_be_person(inside, grid, wait=5)  # in the workspace: at once


def test_the_tracker_confirms_at_the_end_what_a_longer_rule_would_have_waited_for():
    tr = Tracker(min_hits=2, gate=0.3, reid_gate=3.0, contact=0.8)
    tr.may_confirm = lambda t: False  # nothing is confirmed during the run
    for step in range(4):
        tr.update(step, np.array([[0.0, 0.0], [0.6, 0.0]]))
    assert tr.n_persons == 0
    tr.finish(3, lambda t: t.position[0] > 0.3)  # only the second
    assert [t.person for t in sorted(tr.tracks, key=lambda t: t.key)] == [0, 1]
    tr.finish(3, lambda t: True)  # then the first, a new id: the person seen at the last step is not lost
    assert [t.person for t in sorted(tr.tracks, key=lambda t: t.key)] == [2, 1]


def test_the_tracker_vouches_for_detections_where_a_person_seen_lately_is_predicted():
    tr = Tracker(min_hits=1, gate=0.3, growth=0.1, recent=2, max_misses=10)
    for step in range(3):  # a person walking +x at 0.1 m a step
        tr.update(step, np.array([[0.1 * step, 0.0]]))
    assert tr.n_persons == 1
    # at step 3 they are predicted at x = 0.3: within the gate yes, 0.5 m off no
    assert tr.vouched(np.array([[0.32, 0.05], [0.8, 0.0]]), 3).tolist() == [True, False]
    tr.update(3, np.zeros((0, 2)))
    tr.update(4, np.zeros((0, 2)))  # missed twice: the gate grew by 0.1 m a step unseen after the first
    assert tr.vouched(np.array([[0.55, 0.0]]), 5).tolist() == [True]
    tr.update(5, np.zeros((0, 2)))  # missed more than ``recent`` steps: nobody vouches any more
    assert tr.vouched(np.array([[0.6, 0.0]]), 6).tolist() == [False]
    assert Tracker().vouched(np.array([[0.0, 0.0]]), 0).tolist() == [False]  # no tracks
