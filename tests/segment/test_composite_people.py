"""Frames of several people in their own clothes (silpose.segment.composite.composite_people)."""

import numpy as np

from silpose.segment.composite import composite_people, room


def test_nearer_people_cover_farther_ones_in_their_own_shirts_and_trousers():
    h, w = 120, 160
    masks = np.zeros((2, h, w), bool)
    masks[0, 20:100, 30:70] = True  # far person
    masks[1, 30:110, 55:95] = True  # near person, overlapping the far one's right side
    clothes = np.array([[[200, 40, 40], [40, 40, 200]], [[40, 200, 40], [200, 200, 40]]], np.uint8)
    img = composite_people(masks, clothes, np.array([0, 1]), camera=0, frame=3, noise_std=0.0, flicker=0.0)
    clean = room(0, (w, h))

    def near(region, colour):  # cloth = colour minus stripes (0 or 25) and a texture in [0, ~10]
        d = np.asarray(colour, float)[None] - img[region].astype(float)
        return np.all((d > -2) & (d < 45), axis=1).mean()

    only_far_top = np.zeros((h, w), bool)
    only_far_top[22:50, 32:52] = True
    only_far_legs = np.zeros((h, w), bool)
    only_far_legs[70:98, 32:52] = True
    both_top = np.zeros((h, w), bool)
    both_top[40:60, 58:68] = True  # the near person's shirt rows, where both overlap
    assert near(only_far_top, clothes[0, 0]) > 0.95 and near(only_far_legs, clothes[0, 1]) > 0.95
    assert near(both_top, clothes[1, 0]) > 0.95  # the nearer one is painted over
    outside = ~masks.any(axis=0)
    outside[100:, :] = False  # shadows lie beside the feet
    assert np.abs(img[outside].astype(float) - clean[outside]).max() <= 1.0  # the room untouched, no noise
