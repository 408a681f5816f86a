"""The pieces of silpose.app's data path on small hand-made inputs: view contours and their status,
output file names, segmentation scores, and inference on frames that lost every view."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from silpose.app.contours import STATUS_EMPTY, STATUS_OK, STATUS_SMALL, view_contour
from silpose.app.errors import FramesInputError
from silpose.app.inference import infer_rows
from silpose.app.inputs.frames_folder import open_frames
from silpose.app.segment_quality import view_scores
from silpose.app.writers import sibling
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.shared.contours import extract_contour


def test_view_contour_statuses():
    mask = np.zeros((40, 30), bool)
    assert view_contour(mask, 16, min_area=5) == (None, STATUS_EMPTY, 0)
    mask[10:13, 10:13] = True  # a 3 x 3 blob
    area = extract_contour(mask, 16).area
    assert view_contour(mask, 16, min_area=int(area) + 1)[1:] == (STATUS_SMALL, area)
    points, status, got = view_contour(mask, 16)  # no minimum: any blob is used
    assert status == STATUS_OK and got == area and points.shape == (16, 2)
    mask[5:35, 5:25] = True
    points, status, _ = view_contour(mask, 16, min_area=50)
    assert status == STATUS_OK
    np.testing.assert_array_equal(points, extract_contour(mask, 16).points)


def test_sibling_names_the_outputs_after_the_joints_file():
    assert sibling(Path("out/j.parquet"), ".contours.npz") == Path("out/j.contours.npz")
    assert sibling(Path("a.b.json"), ".overlays") == Path("a.b.overlays")


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


def test_frames_without_a_usable_view_get_nan_rows():
    data = make_linear_shapes(120, n_views=3, n_points=12, seed=2)
    model = ShapeStructureModel(1, 3, n_init=1, max_iter=10, noise_variance=1e-3).fit(data.contours[:100],
                                                                                       data.joints[:100])
    contours = data.contours[100:].astype(np.float64)
    present = np.ones((20, 3), bool)
    present[[3, 7]] = False
    contours[~present] = np.nan
    res = infer_rows(model, contours, present, None)
    ok = np.flatnonzero(present.any(axis=1))
    ref = model.infer(contours[ok], present[ok])
    np.testing.assert_array_equal(res.joints[ok], ref.joints)
    np.testing.assert_array_equal(res.log_marginal[ok], ref.log_marginal)
    assert np.isnan(res.joints[[3, 7]]).all() and not res.views_present[[3, 7]].any()
    none = infer_rows(model, contours[[3, 7]], present[[3, 7]], None)
    assert np.isnan(none.joints).all() and none.responsibilities.shape == (2, 1)
    with pytest.raises(FramesInputError, match="stores no rig"):
        open_frames(model, Path("."))
