"""silpose.app.segment_quality: segmentation scores count pixels as defined."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.app.segment_quality import view_scores


def test_view_scores_count_pixels():
    truth = np.zeros((20, 20), bool)
    truth[5:15, 5:15] = True  # 100 px
    seg = truth.copy()
    seg[5:15, 15] = True  # 10 px on the boundary (within the grown truth)
    seg[0, 0] = True  # 1 px far away
    s = view_scores(seg, truth, grow_px=2)
    assert s["iou"] == pytest.approx(100 / 111)
    assert s["fp_out"] == 1.0
    assert s["person_iou"] == pytest.approx(100 / 110)
    assert view_scores(np.zeros_like(truth), np.zeros_like(truth))["iou"] == 1.0
