"""Registering an empty-room plate to its recording (``silpose.segment.align``).

References: the warp the test applied itself (known shift and zoom), OpenCV's ``warpAffine`` read pixel by
pixel, and the noise the test added.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.segment import plate_alignment, plate_mismatch_std, warp_plate
from silpose.segment.composite import room

SIZE = (320, 240)  # (W, H)


def _room() -> np.ndarray:
    return np.clip(room(0, SIZE), 0, 255).astype(np.uint8)


def _nudged(img: np.ndarray, warp: np.ndarray) -> np.ndarray:
    return cv2.warpAffine(img, warp, SIZE, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def test_warp_plate_reads_the_frame_where_the_warp_points():
    frame = np.zeros((40, 50), np.uint8)
    frame[12, 30] = 255
    shifted = warp_plate(frame, np.array([[1.0, 0.0, 5.0], [0.0, 1.0, -3.0]]))
    assert np.unravel_index(np.argmax(shifted), shifted.shape) == (15, 25)  # result(x) = frame(x + (5, -3))


def test_plate_alignment_recovers_a_nudge():
    scene = _room()
    truth = np.array([[1.012, 0.003, 2.6], [-0.002, 1.008, -1.7]])  # plate pixel of each recording pixel
    plate = _nudged(scene, truth)  # the plate's camera sat elsewhere: scene(x) = plate(truth x)
    warp = plate_alignment(plate, scene)
    assert warp is not None
    # the recovered warp maps every pixel of the image to within 0.1 px of where the true one does
    ys, xs = np.mgrid[0:SIZE[1]:16, 0:SIZE[0]:16]
    pts = np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
    assert np.abs(warp @ pts - truth @ pts).max() < 0.1
    inner = (slice(10, -10), slice(10, -10))
    before = np.abs(plate.astype(int) - scene)[inner].mean()
    after = np.abs(warp_plate(plate, warp).astype(int) - scene)[inner].mean()
    assert after < 0.25 * before


def test_plate_alignment_keeps_the_identity_for_an_aligned_plate_and_refuses_another_view():
    scene = _room()
    noisy = np.clip(scene + np.random.default_rng(0).normal(0, 3, scene.shape), 0, 255).astype(np.uint8)
    assert plate_alignment(noisy, scene) is None  # nothing to gain
    far = _nudged(scene, np.array([[1.0, 0.0, 40.0], [0.0, 1.0, 0.0]]))  # 40 px: not a nudge
    assert plate_alignment(far, scene) is None
    with pytest.raises(ValueError, match="differ in size"):
        plate_alignment(scene[:100], scene)


def test_plate_mismatch_std_measures_the_rooms_difference_not_the_people():
    rng = np.random.default_rng(1)
    plate = _room().astype(np.float32)
    recording = plate * 0.8 + rng.normal(0, 5.0, plate.shape)  # darker, and 5 graylevels of difference
    people = rng.random(plate.shape[:2]) < 0.1  # 10 % of the pixels show someone (the room view is a median)
    recording[people] = rng.uniform(0, 255, (int(people.sum()), 3))
    s = plate_mismatch_std(plate.astype(np.uint8), np.clip(recording, 0, 255).astype(np.uint8))
    assert 5.0 / 0.8 * 0.9 < s < 5.0 / 0.8 * 1.25, s  # the difference, in the plate's graylevels
    assert plate_mismatch_std(plate.astype(np.uint8), plate.astype(np.uint8)) == 0.0
