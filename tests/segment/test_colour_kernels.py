"""The compiled colour pass of background subtraction (``silpose.segment.colour_kernels``) gives OpenCV's answers bit
for bit.

References, computed here with the calls they replace: ``cv2.convertScaleAbs`` channel by channel for the gain's
division (rounding half to even, saturating at 255), float32 ``cv2.subtract`` / ``cv2.multiply`` and
``cv2.transform`` by a row of ones for the squared differences and the scores; on random frames and backgrounds,
gains above and below 1 (values that saturate), and real-valued means.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.segment import BackgroundModel
from silpose.segment.colour_kernels import normalise_and_score

_ONES = np.ones((1, 3), np.float32)


def _opencv_reference(frame, inv, mean32, inv_var, thr):
    divided = cv2.merge([cv2.convertScaleAbs(c, alpha=float(a)) for c, a in zip(cv2.split(frame), inv)])
    d = divided.astype(np.float32)
    cv2.subtract(d, mean32, dst=d)
    cv2.multiply(d, d, dst=d)
    sq = cv2.transform(d, _ONES)
    cv2.multiply(d, inv_var, dst=d)
    score = cv2.transform(d, _ONES)
    return divided, sq, score, score > thr


@pytest.mark.parametrize("shape", [(1, 1), (7, 13), (48, 64)])
def test_normalise_and_score_is_opencvs_arithmetic(shape):
    rng = np.random.default_rng(shape[1])
    h, w = shape
    for trial in range(30):
        frame = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        mean32 = rng.uniform(0, 255, (h, w, 3)).astype(np.float32)
        inv_var = (1.0 / rng.uniform(1, 30, (h, w, 3)) ** 2).astype(np.float32)
        inv = rng.uniform(0.4, 2.5, 3).astype(np.float32) if trial else np.ones(3, np.float32)
        thr = np.float32(3.0 * rng.uniform(1, 4) ** 2)
        want = _opencv_reference(frame, inv, mean32, inv_var, thr)
        out = np.empty_like(frame)
        sq, score, cand = (np.empty((h, w), t) for t in (np.float32, np.float32, bool))
        normalise_and_score(frame.reshape(h, 3 * w), np.tile(inv, w), mean32.reshape(h, 3 * w),
                            inv_var.reshape(h, 3 * w), thr, out.reshape(h, 3 * w), sq, score, cand)
        for got, ref in zip((out, sq, score, cand), want):
            np.testing.assert_array_equal(got, ref)
    assert want[0].max() == 255  # gains above 1 saturated somewhere: the clip was exercised


def test_colour_segmentation_divides_each_frame_by_its_own_gain():
    """Through the model: a frame lit 1.3x brighter than its background has the background's candidates once its
    gain is divided out (the kernel receives the gain frame_gain measures), and none of it is foreground."""
    rng = np.random.default_rng(5)
    room = rng.integers(40, 160, (60, 80, 3), dtype=np.uint8)
    frames = np.clip(room[None] + rng.normal(0, 2, (6, 60, 80, 3)), 0, 255).astype(np.uint8)
    model = BackgroundModel(gain=True, largest_blob=False).fit(frames)
    lit = np.clip(np.rint(frames[0] * 1.3), 0, 255).astype(np.uint8)
    np.testing.assert_allclose(model.frame_gain(lit), 1.3, atol=0.02)
    assert model.segment(lit).mean() < 0.01
    assert BackgroundModel(gain=False, largest_blob=False).fit(frames).segment(lit).mean() > 0.5
