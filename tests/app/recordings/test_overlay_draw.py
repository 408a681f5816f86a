"""The overlay drawing's vectorised pieces against the per-item loops they replace."""

import cv2
import numpy as np

from silpose.app.recordings.overlay_video import dashes, draw_frame
from silpose.shared.skeleton import BONES


def test_dashes_are_every_other_pair_of_segments():
    for n in range(0, 14):
        q = np.arange(2 * n, dtype=np.int32).reshape(n, 2)
        want = [q[i : i + 3] for i in range(0, len(q), 4) if len(q[i : i + 3]) >= 2]
        got = dashes(q)
        assert len(got) == len(want)
        for a, b in zip(got, want):
            np.testing.assert_array_equal(a, b)


def test_skeleton_is_drawn_bone_by_bone():
    rng = np.random.default_rng(0)
    joints = rng.uniform(20, 200, (19, 2))
    img = draw_frame(None, (240, 220), "cam", 0, [{"person": 1, "status": "ok", "outline": None, "recon": None,
                                                    "joints_px": joints, "anchor_px": None}])
    ref = np.zeros((220, 240, 3), np.uint8)
    q = np.round(joints * 16).astype(np.int32)
    cv2.polylines(ref, [q[list(bone)] for bone in BONES], False, (60, 180, 255), 2, cv2.LINE_AA, shift=4)
    top = joints[:, 1].argmin()
    cv2.putText(ref, "#1", (int(joints[top, 0]) - 10, max(int(joints[top, 1]) - 12, 14)), cv2.FONT_HERSHEY_SIMPLEX,
                0.5, (60, 180, 255), 1, cv2.LINE_AA)
    cv2.putText(ref, "cam  frame 0", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (230, 230, 230), 1, cv2.LINE_AA)
    np.testing.assert_array_equal(img, ref)
