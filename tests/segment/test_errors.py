"""Every bad input to BackgroundModel gives a SegmentError naming the argument."""

import numpy as np
import pytest

from silpose.segment import BackgroundModel, SegmentError

U8 = np.uint8
BG = np.zeros((3, 12, 16), U8)


def _fitted(**params):
    return BackgroundModel(**params).fit(BG)


def _one_frame_then_segment():
    BackgroundModel().partial_fit(BG[:1]).segment(BG[0])


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: BackgroundModel().fit([]), r"^frames: no frames given"),
        (lambda: BackgroundModel().fit(np.zeros((0, 12, 16), U8)), r"^frames: no frames given"),
        (lambda: BackgroundModel().partial_fit(np.zeros((0, 12, 16, 3), U8)), r"^frames: no frames given"),
        (lambda: BackgroundModel().fit(BG.astype(np.float32)), r"^frames\[0\]: expected dtype uint8, got float32"),
        (lambda: BackgroundModel().fit(BG[0]), r"^frames: expected a stack of frames .* got shape \(12, 16\)"),
        (lambda: BackgroundModel().fit(np.zeros((3, 12, 16, 4), U8)), r"^frames\[0\]: colour frames need 3 channels"),
        (lambda: BackgroundModel().fit(BG[:1]), r"^frames: a background needs at least 2 frames, got 1"),
        (lambda: BackgroundModel().fit([BG[0], np.zeros((12, 15), U8)]), r"^frames\[1\]: frame size 15x12"),
        (lambda: BackgroundModel().fit([BG[0], np.zeros((12, 16), np.int16)]), r"^frames\[1\]: expected dtype uint8"),
        (lambda: BackgroundModel().fit(BG).partial_fit(np.zeros((2, 10, 16), U8)), r"^frames: frame size 16x10 .* differs from the background's 16x12"),
        (lambda: BackgroundModel().segment(BG[0]), r"not fitted; call fit"),
        (lambda: BackgroundModel().segment_batch(BG), r"not fitted; call fit"),
        (_one_frame_then_segment, r"the background has 1 frame; at least 2"),
        (lambda: _fitted().segment(np.zeros((12, 15), U8)), r"^frame: frame size 15x12"),
        (lambda: _fitted().segment(BG[0].astype(float)), r"^frame: expected dtype uint8, got float64"),
        (lambda: _fitted().segment(BG), r"^frame: colour frames need 3 channels"),
        (lambda: _fitted().segment_batch(BG[0]), r"^frames: expected a stack of frames"),
        (lambda: _fitted().segment_batch(np.zeros((2, 12, 17), U8)), r"^frames: frame size 17x12"),
        (lambda: _fitted(ncc_window=4), r"^ncc_window: must be an odd integer in \[3, 63\], got 4"),
        (lambda: _fitted(ncc_window=65), r"^ncc_window: must be an odd integer in \[3, 63\], got 65"),
        (lambda: _fitted(k_sigma=-1), r"^k_sigma: must be a positive number"),
        (lambda: _fitted(min_std=-0.5), r"^min_std: must be a number >= 0"),
        (lambda: _fitted(ncc_threshold=1.5), r"^ncc_threshold: must be None or a number"),
        (lambda: _fitted(shadow_ratio=(1.0, 0.5)), r"^shadow_ratio: must be \(low, high\)"),
        (lambda: _fitted(median_size=4), r"^median_size: must be an odd integer"),
        (lambda: _fitted(open_size=2.5), r"^open_size: must be an integer"),
        (lambda: _fitted(ncc_support="everything"), r"^ncc_support: must be"),
        (lambda: _fitted(noise_correction="yes"), r"^noise_correction: must be True or False"),
        (lambda: _fitted(largest_blob=None), r"^largest_blob: must be True or False"),
        (lambda: _fitted(min_support=2), r"^min_support: must be a number in \[0, 1\]"),
    ],
)
def test_bad_input_gives_a_clear_error(call, match):
    with pytest.raises(SegmentError, match=match):
        call()


def test_segment_error_is_caught_as_a_value_error():
    """Callers may catch ValueError (the documented contract): a real bad call is one, naming the argument."""
    with pytest.raises(ValueError, match=r"^frames\[0\]: expected dtype uint8") as info:
        BackgroundModel().fit(BG.astype(np.float64))
    assert type(info.value) is SegmentError
