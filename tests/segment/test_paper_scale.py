"""Paper-scale check (section 6: 400 background images, 320x240 views), selected with -m slow.

The background streams through partial_fit in chunks of 50, as a long capture would; CI runs the
small-scene versions in test_background.py.
"""

import numpy as np
import pytest

from silpose.segment import BackgroundModel
from silpose.segment.synthetic import render_scene


@pytest.mark.slow
@pytest.mark.parametrize("seed", [21, 22])
def test_400_background_frames_streamed_in_chunks(seed):
    scene = render_scene(n_background=400, n_frames=20, size=(320, 240), seed=seed)
    model = BackgroundModel()
    for start in range(0, 400, 50):
        model.partial_fit(scene.background[start : start + 50])
    assert model.n_frames_seen_ == 400
    masks = model.segment_batch(scene.frames)
    ious = (masks & scene.masks).sum(axis=(1, 2)) / (masks | scene.masks).sum(axis=(1, 2))
    kept = (masks & scene.shadows).sum() / scene.shadows.sum()
    plain = BackgroundModel(ncc_threshold=None).fit(scene.background).segment_batch(scene.frames)
    kept_plain = (plain & scene.shadows).sum() / scene.shadows.sum()
    print(f"seed {seed}: IoU min {ious.min():.3f} mean {ious.mean():.3f}; shadow kept {kept:.3f} (plain {kept_plain:.3f})")
    assert ious.min() >= 0.9
    assert kept < 0.15 and kept_plain > 0.9
