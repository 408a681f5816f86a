"""Shape-vector layout (paper eq. 4): block order, weights, round trip, masks, JSON."""

import numpy as np
import pytest

from silpose.model.features import FeatureLayout
from silpose.shared.skeleton import N_JOINTS, ROOT


def _data(n=5, k=3, p=7, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, k, p, 2)), rng.normal(size=(n, N_JOINTS, 3))


def test_layout_sizes_and_block_positions_match_eq4():
    lay = FeatureLayout(views=(2, 0, 1), n_points=7, structure_weight=2.5)
    c, j = _data()
    X = lay.build(c, j)
    assert X.shape == (5, 3 * 7 * 2 + 57) == (5, lay.dim)
    # brute-force reference: explicit loop over views, points and coordinates (x0, y0, x1, y1, ...)
    rel = j - j[:, ROOT : ROOT + 1]
    for r in range(5):
        ref = []
        for k in range(3):
            for i in range(7):
                ref += [c[r, k, i, 0], c[r, k, i, 1]]
        ref += list(2.5 * rel[r].ravel())
        np.testing.assert_array_equal(X[r], np.array(ref))
    np.testing.assert_array_equal(X[:, lay.view_slice(1)], c[:, 1].reshape(5, -1))
    assert lay.structure_slice == slice(42, 99)


def test_split_inverts_build_with_root_relative_joints():
    lay = FeatureLayout(views=(0, 1, 2), n_points=7, structure_weight=0.3)
    c, j = _data(seed=1)
    c2, j2 = lay.split(lay.build(c, j))
    np.testing.assert_allclose(c2, c, rtol=0, atol=0)
    np.testing.assert_allclose(j2, j - j[:, ROOT : ROOT + 1], atol=1e-14)
    assert np.all(j2[:, ROOT] == 0)


def test_observed_masks():
    lay = FeatureLayout(views=(3, 1), n_points=4)
    m = lay.observed_mask([False, True])
    assert m.shape == (lay.dim,)
    assert not m[:8].any() and m[8:16].all() and not m[16:].any()
    np.testing.assert_array_equal(lay.observed_mask_for_views([1]), m)
    np.testing.assert_array_equal(lay.observed_mask_for_views([3, 1]), np.r_[np.ones(16, bool), np.zeros(57, bool)])
    with pytest.raises(ValueError, match="not modelled"):
        lay.observed_mask_for_views([0])
    with pytest.raises(ValueError, match="shape"):
        lay.observed_mask([True])


def test_json_round_trip_and_bad_json():
    lay = FeatureLayout(views=(1, 3), n_points=200, structure_weight=4.0)
    assert FeatureLayout.from_json(lay.to_json()) == lay
    with pytest.raises(ValueError, match="missing field 'n_points'"):
        FeatureLayout.from_dict({"views": [0], "n_joints": 19, "structure_weight": 1.0})
    with pytest.raises(ValueError, match="version"):
        FeatureLayout.from_dict({**lay.to_dict(), "layout_version": 99})
    with pytest.raises(ValueError, match="not valid JSON"):
        FeatureLayout.from_json("{nope")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(views=(), n_points=5), "at least one"),
        (dict(views=(0, 0), n_points=5), "distinct"),
        (dict(views=(0,), n_points=5, structure_weight=0.0), "structure_weight"),
        (dict(views=(0,), n_points=2), "n_points"),
    ],
)
def test_invalid_layouts(kwargs, match):
    with pytest.raises(ValueError, match=match):
        FeatureLayout(**kwargs)


def test_build_shape_errors():
    lay = FeatureLayout(views=(0, 1), n_points=7)
    c, j = _data(k=3)
    with pytest.raises(ValueError, match="contours_norm must have shape"):
        lay.build(c, j)
    with pytest.raises(ValueError, match="rows"):
        lay.build(c[:, :2], j[:3])
    with pytest.raises(ValueError, match="X must have shape"):
        lay.split(np.zeros((2, 5)))
