"""BackgroundModel's additions for real rooms: the lighting gain, the robust (median) background, absorb."""

import numpy as np
import pytest

from silpose.segment import BackgroundModel, SegmentError
from silpose.segment.synthetic import render_scene
from silpose.shared.metrics import mask_iou


@pytest.fixture(scope="module")
def scene():
    return render_scene(n_background=12, n_frames=6, size=(160, 120), seed=3)


def test_gain_undoes_a_brighter_recording(scene):
    lit = np.clip(scene.frames.astype(np.float32) * np.array([1.3, 1.25, 1.2], np.float32), 0, 255).astype(np.uint8)
    plain = BackgroundModel().fit(scene.background)
    gained = BackgroundModel(gain=True).fit(scene.background)
    assert mask_iou(plain.segment_batch(lit), scene.masks).mean() < 0.3  # the whole frame is foreground
    assert mask_iou(gained.segment_batch(lit), scene.masks).mean() > 0.9
    # same light: the gain changes nothing that matters
    same = mask_iou(gained.segment_batch(scene.frames), scene.masks).mean()
    assert abs(same - mask_iou(plain.segment_batch(scene.frames), scene.masks).mean()) < 0.01
    g = gained.frame_gain(lit[0])
    assert g.shape == (3,) and np.allclose(g, [1.3, 1.25, 1.2], atol=0.04)


def test_fit_robust_learns_the_room_from_frames_with_people(scene):
    # the room's frames with the figure at 6 places, plus a few empty ones: the median is the room
    frames = np.concatenate([scene.frames, scene.background[:3]])
    robust = BackgroundModel().fit_robust(frames)
    clean = scene.clean_background.astype(np.float64) @ np.array([0.114, 0.587, 0.299])
    covered = scene.masks.sum(axis=0) >= 5  # where the figure stood in more than half of the frames
    err = np.abs(robust.mean_ - clean)[~covered]
    assert np.median(err) < 2.0 and np.percentile(err, 99) < 8.0
    with pytest.raises(SegmentError, match="fit_robust"):
        robust.partial_fit(scene.background[:2])


def test_absorb_makes_a_static_object_background(scene):
    model = BackgroundModel(largest_blob=False).fit(scene.background)
    before = model.segment_batch(scene.frames)
    frame = scene.background[0].copy()
    frame[20:50, 100:130] = (40, 200, 40)  # a green box that was not in the background
    assert model.segment(frame)[20:50, 100:130].mean() > 0.9
    where = np.zeros(frame.shape[:2], bool)
    where[20:50, 100:130] = True
    model.absorb(frame, where)
    assert model.segment(frame).sum() < 20  # gone: only noise left
    far = np.ones(where.shape, bool)
    far[10:60, 90:140] = False  # beyond the box and the filters' reach (NCC window, median, morphology)
    assert np.array_equal(model.segment_batch(scene.frames)[:, far], before[:, far])  # the rest is untouched
