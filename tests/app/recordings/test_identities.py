"""Identities that hold (``silpose infer --videos``): one id per person through crossings and occlusions.

Four "people" (upright cylinders, ``conftest.cylinder_masks``) walk in front of the lab rig's four cameras for
4 s at 25 fps: two pairs cross, and one person is hidden from every camera for 1.2 s (a pillar between them
and the wall of cameras) while walking on. Scored against the cylinders' true floor paths by
:func:`benchmarks.recording_scores.score_rows` (people, identity switches). Measured: this tracker 4 ids, 2
switches (one pair's ids exchanged while their hulls were one detection, restored when they parted); the
tracker before lost tracks and re-identification (lost after 0.5 s, 3 hits, 0.6 m gate) 9 ids, 4 switches.
That 4 / 2 relied on a re-identification that wrote one id at two places: person 3, re-emerging at frame 70,
took person 1's id at frame 77 while person 1 had been seen 0.97 m away until frame 74. A person seen after a
new track began, farther from it than two people in contact (``CONTACT_M``), is no longer that track: 5 ids, 3
switches, no id at two places (the lab recording of ``benchmarks.identities`` keeps 4 ids, 2 switches).
"""

import numpy as np
import pytest

from benchmarks.recording_scores import read_rows, score_rows
from silpose.app.recordings.pipeline import RecordingOptions, run_recording
from silpose.app.recordings.tracking import Tracker

N = 100  # frames, 4 s at 25 fps
HIDDEN = range(40, 70)  # frames where person 3 is hidden from every camera


def _paths(tools) -> np.ndarray:
    """(N, 4, 2) metres: the four people's floor points."""
    return np.stack([tools.walk((-1.3, -0.6), (1.3, -0.5), N), tools.walk((1.3, -0.3), (-1.3, -0.8), N),
                     tools.walk((-1.2, 0.7), (1.2, 0.9), N), tools.walk((1.2, 1.3), (-1.0, 0.3), N)], axis=1)


@pytest.fixture(scope="module")
def recording(rig, tools, tmp_path_factory):
    paths = _paths(tools)
    folder = tmp_path_factory.mktemp("ids") / "videos"
    folder.mkdir()
    frames = np.zeros((len(rig), N, rig.image_size[1], rig.image_size[0]), np.uint8)
    for f in range(N):
        shown = paths[f] if f not in HIDDEN else paths[f, :3]
        frames[:, f] = tools.cylinder_masks(rig, shown)
    for k, cam in enumerate(rig):
        tools.write_video(folder / f"{cam.name}.mp4", frames[k])
    truth = np.zeros((N, 4, 19, 3))
    truth[:, :, 0, :2] = paths
    truth[:, :, 0, 2] = 0.9
    return folder, truth


def test_one_id_per_person_through_crossings_and_an_occlusion(tiny_model, recording, tmp_path):
    folder, truth = recording
    s = run_recording(tiny_model, folder, tmp_path / "o", RecordingOptions(masks=True, overlays=False))
    sc = score_rows(read_rows(tmp_path / "o" / "joints.parquet"), truth)
    assert sc["paired"] >= 0.8 * 4 * N - 4 * len(HIDDEN)  # the people were found
    assert s.n_persons == sc["persons"] <= 5 and sc["identity_switches"] <= 3 and sc["false_rows"] <= 10
    rows = read_rows(tmp_path / "o" / "joints.parquet")
    pairs = list(zip(rows["frame"], rows["person"]))
    assert len(pairs) == len(set(pairs))  # one row per id and frame: an id is one person at a time


def test_a_person_lost_for_a_second_keeps_their_id():
    """Tracker alone: a person unseen for 30 steps comes back 1.1 m from where they were lost (walking at
    0.04 m per step); a one-step ghost elsewhere never becomes a person."""
    tr = Tracker(min_hits=3, max_misses=100, growth=0.02, reid_gate=3.0, smoothing=0.2)
    for step in range(60):
        det = [np.array([-1.0, 0.0]) + [0.04 * step, 0.0], np.array([0.0, 1.0])]
        if 20 <= step < 50:
            det = det[1:]
        if step == 55:
            det.append(np.array([1.5, -1.0]))
        out = tr.update(step, np.array(det))
    assert tr.n_persons == 2 and sorted(t.person for t, d in out if d >= 0) == [1, 2]


@pytest.mark.parametrize("reid_speed, ids", [(0.0, 1), (0.05, 2)])
def test_a_lost_person_does_not_reappear_where_they_could_not_have_gone(reid_speed, ids):
    """Tracker alone, 60 steps a second: a person standing at (0, 0) is lost at step 20; from step 21 someone else
    stands 1.3 m away. Re-identified by distance alone (within the 3 m gate) they would be the lost person, 1.3 m in
    one step (78 m/s); at a jog's 3 m/s (0.05 m per step) they are someone new. The lost person's id still goes to
    whoever stands where they could have walked (test above)."""
    tr = Tracker(min_hits=3, max_misses=100, growth=0.02, reid_gate=3.0, smoothing=0.2, reid_speed=reid_speed)
    for step in range(40):
        det = [np.array([0.0, 0.0])] if step < 20 else [np.array([1.3, 0.0])] if step > 20 else []
        tr.update(step, np.array(det).reshape(-1, 2))
    assert tr.n_persons == ids


def test_the_pipelines_tracker_bounds_re_identification_by_a_run():
    from silpose.app.recordings.tracking import REID_SPEED_M_S, tracker_for_fps

    assert tracker_for_fps(60.0).reid_speed == pytest.approx(REID_SPEED_M_S / 60.0)
