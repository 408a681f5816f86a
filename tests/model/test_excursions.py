"""Excursions (shadows, blobs, bitten holes) trimmed from observed contours (silpose.model.robust.excursions)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.model.robust.excursions import ExcursionSettings, excursion_runs, point_to_polygon_distance, trim_excursions
from silpose.model.robust import RobustSettings
from silpose.shared.contours import extract_contour

N = 200


def _person_mask(shadow: int = 0, blob: bool = False) -> np.ndarray:
    """(240, 320) uint8 mask of a standing figure (head, torso, two legs); ``shadow`` px: a flat ellipse
    sideways at the feet (as the eval's mask noise draws one); ``blob``: a disc joined to the right arm by a
    thin bridge (a spurious foreground blob)."""
    m = np.zeros((240, 320), np.uint8)
    cv2.circle(m, (160, 60), 12, 1, -1)
    cv2.rectangle(m, (140, 72), (180, 140), 1, -1)
    cv2.rectangle(m, (143, 140), (156, 200), 1, -1)
    cv2.rectangle(m, (164, 140), (177, 200), 1, -1)
    cv2.rectangle(m, (128, 76), (139, 130), 1, -1)
    cv2.rectangle(m, (181, 76), (192, 130), 1, -1)
    if shadow:
        cv2.ellipse(m, (160 + shadow, 199), (shadow, 3), 0, 0, 360, 1, -1)
    if blob:
        cv2.circle(m, (210, 100), 8, 1, -1)
        cv2.rectangle(m, (192, 99), (203, 101), 1, -1)
    return m


def _contour(mask) -> np.ndarray:
    return extract_contour(mask, N).points.astype(np.float64)


def test_point_to_polygon_distance_against_a_dense_polyline():
    rng = np.random.default_rng(0)
    poly = _contour(_person_mask())
    dense = np.concatenate([poly + t * (np.roll(poly, -1, axis=0) - poly) for t in np.linspace(0, 1, 200)])
    pts = rng.uniform([120, 40], [200, 210], (300, 2))
    brute = np.min(np.linalg.norm(pts[:, None] - dense[None], axis=-1), axis=1)
    got = point_to_polygon_distance(pts[None], poly[None])[0]
    np.testing.assert_allclose(got, brute, atol=0.05)  # the dense polyline's spacing bounds its error
    assert np.all(got <= brute + 1e-9)


def test_excursion_runs_are_the_cyclic_runs():
    rng = np.random.default_rng(1)
    for _ in range(200):
        flags = rng.uniform(size=17) < rng.uniform(0.1, 0.9)
        runs = excursion_runs(flags)
        covered = np.concatenate(runs) if runs else np.array([], int)
        assert sorted(covered.tolist()) == np.flatnonzero(flags).tolist()  # every flagged point once
        for run in runs:  # consecutive indices (mod n), bounded by unflagged points
            assert np.all(np.diff(run) % 17 == 1)
            if len(run) < 17:
                assert not flags[(run[0] - 1) % 17] and not flags[(run[-1] + 1) % 17]
    assert [r.tolist() for r in excursion_runs(np.array([1, 1, 0, 0, 1], bool))] == [[4, 0, 1]]


@pytest.mark.parametrize("kind", ["shadow", "blob"])
def test_an_excursion_is_cut_and_the_points_re_indexed(kind):
    clean = _contour(_person_mask())
    dirty = _contour(_person_mask(shadow=25) if kind == "shadow" else _person_mask(blob=True))
    # the clean outline stands in for the reconstruction
    trimmed, changed = trim_excursions(dirty[None, None], clean[None, None], np.ones((1, 1), bool))
    assert changed[0, 0]
    before = np.linalg.norm(dirty - clean, axis=-1)
    after = np.linalg.norm(trimmed[0, 0] - clean, axis=-1)
    # the loop lengthened the outline, which shifted the points after it: trimming undoes both
    assert before.mean() > 3.0 and after.mean() < 0.4 * before.mean(), (before.mean(), after.mean())
    assert np.abs(trimmed[0, 0, 0] - dirty[0]).max() < 1e-9  # the start point (top of the head) stays


def test_clean_and_displaced_outlines_are_left_alone(moved_in_place):
    clean = _contour(_person_mask())
    jittered, patched = moved_in_place(clean)
    batch = np.stack([clean, jittered, patched])[:, None]
    out, changed = trim_excursions(batch, np.repeat(clean[None, None], 3, axis=0), np.ones((3, 1), bool))
    assert not changed.any()
    np.testing.assert_array_equal(out, batch)
    # absent views and NaN reconstructions are skipped
    out, changed = trim_excursions(batch, np.full_like(batch, np.nan), np.ones((3, 1), bool))
    assert not changed.any()
    with pytest.raises(ValueError, match="ratio"):
        ExcursionSettings(ratio=0)


def test_infer_trims_only_frames_with_excursions(fitted_person_model):
    model, contours = fitted_person_model
    plain = model.infer(contours, robust=RobustSettings(excursion_passes=0))
    res = model.infer(contours, robust=True)
    assert res.excursions_trimmed is not None and plain.excursions_trimmed is not None
    untouched = ~res.excursions_trimmed.any(axis=1)
    np.testing.assert_array_equal(res.joints[untouched], plain.joints[untouched])
    assert res.excursions_trimmed[-1].any()  # the shadowed frame
    np.testing.assert_array_equal(res.log_marginal, plain.log_marginal)  # of the input as observed


@pytest.fixture(scope="module")
def fitted_person_model():
    """A one-view model of the figure in many stances (arm and leg lengths varied), and inputs: clean
    stances plus one with a shadow."""
    from silpose.model.shape_model import ShapeStructureModel

    rng = np.random.default_rng(0)
    contours, joints = [], []
    for _ in range(120):
        m = np.zeros((240, 320), np.uint8)
        leg, arm, head = rng.integers(50, 66), rng.integers(45, 60), rng.integers(10, 14)
        cv2.circle(m, (160, 60), int(head), 1, -1)
        cv2.rectangle(m, (140, 72), (180, 140), 1, -1)
        cv2.rectangle(m, (143, 140), (156, 140 + int(leg)), 1, -1)
        cv2.rectangle(m, (164, 140), (177, 140 + int(leg)), 1, -1)
        cv2.rectangle(m, (128, 76), (139, 76 + int(arm)), 1, -1)
        cv2.rectangle(m, (181, 76), (192, 76 + int(arm)), 1, -1)
        contours.append(_contour(m))
        j = np.zeros((19, 3))
        j[:, 2] = np.linspace(0, 1, 19) * (leg + 100) / 100
        joints.append(j)
    contours, joints = np.stack(contours)[:, None], np.stack(joints)
    model = ShapeStructureModel(n_components=2, n_latent=4, structure_weight=1.0, n_init=1, random_state=0,
                                joint_frame="metres").fit(contours[:100], joints[:100])
    inputs = np.concatenate([contours[100:], _contour(_person_mask(shadow=25))[None, None]])
    return model, inputs
