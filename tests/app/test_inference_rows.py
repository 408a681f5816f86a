"""silpose.app.inference.infer_rows: frames that lost every view get NaN rows, the others equal the model's
inference; a model without a rig cannot read a frames folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from silpose.app.errors import FramesInputError
from silpose.app.inference import infer_rows
from silpose.app.inputs.frames_folder import open_frames
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes


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
