"""The synthetic lab recording's walkers differ as people do (silpose.datagen.lab): statures from their own
stream, clothing colours of their test sample."""

import numpy as np

from silpose.datagen.frames.scene import draw_appearance
from silpose.datagen.lab import (DEFAULT_WALKERS, FOUR_WALKERS, FOUR_WALKERS_APART, STATURE_MEAN_M, STATURE_RANGE_M, STATURE_STD_M, Walker,
                                 closest_approach, walker_clothing_bgr, walker_scene, walker_state, walker_stature,
                                 lab_rig)


def test_statures_are_a_pure_function_of_seed_and_index_with_adults_spread():
    walkers = [Walker(index=i, start=(0, 0), end=(1, 0)) for i in range(400)]
    s = np.array([walker_stature(0, w) for w in walkers])
    assert np.array_equal(s, [walker_stature(0, w) for w in walkers])  # deterministic
    assert not np.array_equal(s, [walker_stature(1, w) for w in walkers])  # the seed matters
    assert abs(s.mean() - STATURE_MEAN_M) < 0.015 and abs(s.std() - STATURE_STD_M) < 0.015
    assert s.min() >= STATURE_RANGE_M[0] and s.max() <= STATURE_RANGE_M[1]
    assert walker_stature(0, Walker(index=0, start=(0, 0), end=(1, 0), stature=1.6)) == 1.6
    four = [walker_stature(0, w) for w in FOUR_WALKERS]
    assert np.ptp(four) > 0.1  # seed 0's first four test samples were all 1.91-1.93 m before
    scene = walker_scene(0, FOUR_WALKERS[3], 0.4, lab_rig())
    assert scene.subject["height"] == four[3]


def test_clothing_colours_are_the_samples_linear_colours_in_srgb():
    for w in FOUR_WALKERS:
        bgr = walker_clothing_bgr(0, w)
        look = draw_appearance(0, w.index)
        c = bgr[:, ::-1].astype(float) / 255  # RGB, sRGB-encoded
        linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)  # the sRGB decoding
        assert bgr.dtype == np.uint8 and bgr.shape == (2, 3)
        assert np.allclose(linear, [look["shirt"], look["trousers"]], atol=0.01)


def test_walkers_apart_never_walk_through_each_other():
    """The identities benchmark's plausible recording keeps people apart; its first one has them pass through each
    other. Reference: the distance of every pair at every frame, by hand."""
    frames = 200
    for walkers, lo, hi in ((FOUR_WALKERS_APART, 0.55, np.inf), (FOUR_WALKERS, 0.0, 0.05), (DEFAULT_WALKERS, 0.5, np.inf)):
        gap = np.inf
        for f in range(frames):
            xy = [np.array(walker_state(w, f / 25.0)[:2]) for w in walkers]
            gap = min(gap, min(np.linalg.norm(a - b) for i, a in enumerate(xy) for b in xy[i + 1:]))
        assert lo <= gap < hi and np.isclose(closest_approach(walkers, frames), gap)
    assert [w.index for w in FOUR_WALKERS_APART] == [w.index for w in FOUR_WALKERS]  # the same people
