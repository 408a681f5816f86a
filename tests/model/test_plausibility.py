"""Plausibility: calibration tables per view subset, percentiles, flags, persistence."""

import json

import numpy as np
import pytest

from silpose.model.persistence import ModelFileError, load_model, save_model
from silpose.model.plausibility import (PERCENTILES, PlausibilityCalibration, convex_in_every_view, solidity,
                                       subset_key)
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes


@pytest.fixture(scope="module")
def calibrated():
    data = make_linear_shapes(700, n_views=3, n_points=24, seed=21)
    model = ShapeStructureModel(n_components=2, n_latent=6, structure_weight=2.0, noise_variance=1e-3, n_init=1,
                                random_state=0, joint_frame="metres").fit(data.contours[:400], data.joints[:400])
    model.calibrate_plausibility(data.contours[400:600], seed=1)
    return model, data.contours[600:].astype(np.float64)


def test_tables_cover_every_subset_and_increase(calibrated):
    model, _ = calibrated
    cal = model.plausibility_
    assert sorted(cal.tables) == sorted(["012", "01", "02", "12", "0", "1", "2"])
    for t in cal.tables.values():
        assert t.shape == PERCENTILES.shape and np.all(np.diff(t) >= 0)
    assert cal.n_inputs == 200 and cal.noise_variance == 1e-3


def test_percentile_is_the_share_of_calibration_inputs_below(calibrated):
    model, _ = calibrated
    cal = model.plausibility_
    table = cal.tables["012"]
    present = np.ones((3, 3), bool)
    pct = cal.percentile(np.array([table[0] - 1.0, table[100], table[-1] + 1.0]), present)
    np.testing.assert_allclose(pct, [0.0, 50.0, 100.0])
    # another subset uses its own table
    p2 = np.zeros((1, 3), bool)
    p2[0, [0, 2]] = True
    assert cal.percentile(np.array([cal.tables["02"][20]]), p2)[0] == pytest.approx(10.0)
    assert subset_key(p2[0]) == "02"


def test_genuine_inputs_pass_and_garbage_is_flagged(calibrated):
    model, test = calibrated
    genuine = model.infer(test)
    assert genuine.implausible.mean() < 0.05 and np.nanmedian(genuine.plausibility) > 20
    rng = np.random.default_rng(0)
    garbage = rng.uniform(0, 300, size=(20,) + test.shape[1:])  # scribbles, not shapes of the model
    res = model.infer(garbage)
    assert res.implausible.all() and np.all(res.plausibility == 0.0)
    # another noise variance: the calibration does not apply, no percentiles, no flags
    other = model.infer(test[:5], noise_variance=0.5)
    assert other.plausibility is None and other.implausible is None


def test_calibration_survives_the_model_file(calibrated, tmp_path):
    model, test = calibrated
    path = save_model(tmp_path / "m.npz", model)
    back = load_model(path)
    for key, t in model.plausibility_.tables.items():
        np.testing.assert_array_equal(back.plausibility_.tables[key], t)
    np.testing.assert_array_equal(back.infer(test[:10]).plausibility, model.infer(test[:10]).plausibility)
    # a damaged table is refused with the file and field named
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(bytes(arrays["header"]).decode())
    header["plausibility"]["tables"]["012"] = [0.0] * 5
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    with pytest.raises(ModelFileError, match=r"bad\.npz.*header\.plausibility.*tables\.012"):
        load_model(bad)
    with pytest.raises(ValueError, match="noise_variance"):
        PlausibilityCalibration.from_dict({"tables": {}}, source="x")


def _polygon(corners, n):
    """(n, 2) points along the closed polygon ``corners`` (equal steps in arc length)."""
    c = np.asarray(corners, float)
    seg = np.r_[c[1:], c[:1]] - c
    cum = np.r_[0, np.cumsum(np.linalg.norm(seg, axis=1))]
    t = np.linspace(0, cum[-1], n, endpoint=False)
    i = np.searchsorted(cum, t, side="right") - 1
    return c[i] + seg[i] * ((t - cum[i]) / np.linalg.norm(seg[i], axis=1))[:, None]


def test_solidity_of_known_polygons():
    square = _polygon([[0, 0], [10, 0], [10, 10], [0, 10]], 80)
    ell = _polygon([[0, 0], [20, 0], [20, 10], [10, 10], [10, 20], [0, 20]], 80)  # area 300, hull 350 (perimeter 80: every corner is a point)
    got = solidity(np.stack([square, ell, np.full_like(square, np.nan)]))
    np.testing.assert_allclose(got[:2], [1.0, 300 / 350], rtol=1e-6)
    assert np.isnan(got[2])


def test_convex_in_every_present_view():
    box = _polygon([[0, 0], [10, 0], [10, 30], [0, 30]], 24)
    ell = _polygon([[0, 0], [20, 0], [20, 10], [10, 10], [10, 20], [0, 20]], 24)
    c = np.stack([[box, box, box], [box, ell, box], [box, ell, box], [box, box, box]])
    present = np.array([[1, 1, 1], [1, 1, 1], [1, 0, 1], [0, 0, 0]], bool)
    assert list(convex_in_every_view(c, present)) == [True, False, True, False]  # an absent view does not count


def test_a_box_is_flagged_whatever_its_likelihood(calibrated):
    model, test = calibrated
    genuine = model.infer(test)
    assert not convex_in_every_view(test, np.ones(test.shape[:2], bool)).any()  # the model's shapes are not convex
    centre = np.nanmean(test[:1], axis=2, keepdims=True)
    box = centre + _polygon([[-8, -20], [8, -20], [8, 20], [-8, 20]], test.shape[2])
    res = model.infer(box)
    assert res.implausible.all()
    assert genuine.implausible.mean() < 0.05
