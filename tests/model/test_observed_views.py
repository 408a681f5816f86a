"""The usable observed views of a batch (silpose.model.robust.observed_views): which views, their scale, the output."""

from __future__ import annotations

import numpy as np

from silpose.model.robust.observed_views import observed_views
from silpose.shared.contours import normalise


def test_usable_views_and_their_scales():
    rng = np.random.default_rng(0)
    obs = rng.normal(100, 20, (3, 2, 12, 2))
    rec = obs + rng.normal(0, 1, obs.shape)
    present = np.array([[True, False], [True, True], [True, True]])
    obs[1, 1, 4] = np.nan  # a present view with a NaN point
    rec[2, 0] = np.nan  # a present view without a reconstruction
    ov = observed_views(obs, rec, present)
    assert list(zip(ov.rows.tolist(), ov.views.tolist())) == [(0, 0), (1, 0), (2, 1)]
    np.testing.assert_allclose(ov.scales, normalise(obs[ov.rows, ov.views])[2])  # the normalisation's scale
    np.testing.assert_array_equal(ov.points, obs[ov.rows, ov.views])
    np.testing.assert_array_equal(ov.recon, rec[ov.rows, ov.views])
    # the output is a copy, written view by view
    ov.set(2, np.zeros((12, 2)))
    assert ov.changed.tolist() == [[False, False], [False, False], [False, True]]
    assert np.all(ov.contours[2, 1] == 0) and not np.all(obs[2, 1] == 0)
    np.testing.assert_array_equal(ov.contours[0], obs[0])
    none = observed_views(obs, rec, np.zeros((3, 2), bool))
    assert none.rows.size == 0 and none.scales.shape == (0,) and not none.changed.any()
