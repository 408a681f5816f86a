"""Ragged-outline training augmentation (silpose.model.augment)."""

import numpy as np
import pytest

from silpose.model.augment import ROUGHNESS_STREAM, Roughness, augment_rows, roughen_contours
from silpose.shared.contours import outward_normals
from silpose.shared.seeds import derive_rng, stream_code


def _circles(n_rows=3, k=2, n=200, r=40.0):
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    c = np.stack([100 + r * np.cos(t), 80 + r * np.sin(t)], axis=-1)
    return np.broadcast_to(c, (n_rows, k, n, 2)).copy()


def test_wander_moves_points_along_the_normal_by_the_amplitude():
    c = _circles()
    out = roughen_contours(c, Roughness(amplitude_px=1.0, notches=0.0), seed=0)
    delta = out - c
    nrm = outward_normals(c)
    along = np.einsum("rkni,rkni->rkn", delta, nrm)
    np.testing.assert_allclose(delta, along[..., None] * nrm, atol=1e-12)  # no tangential motion
    np.testing.assert_allclose(along.std(axis=-1), 1.0, rtol=1e-9)  # exactly the amplitude per contour
    # neighbours move together (correlation length 1.5 points), unlike white noise
    corr = np.mean([np.corrcoef(a, np.roll(a, 1))[0, 1] for a in along.reshape(-1, 200)])
    assert corr > 0.7
    # the radius of a circle changes by the normal displacement: a direct, independent check
    radius = np.linalg.norm(out - np.array([100.0, 80.0]), axis=-1)
    np.testing.assert_allclose(radius - 40.0, along, atol=1e-9)


def test_notches_are_dents_or_bumps_of_the_given_depth():
    c = _circles(n_rows=50, k=1)
    out = roughen_contours(c, Roughness(amplitude_px=0.0, notches=1.0, notch_depth_px=3.0, notch_length=6), seed=1)
    along = np.einsum("rkni,rkni->rkn", out - c, outward_normals(c))[:, 0]
    moved = np.abs(along).max(axis=-1)
    assert 0.1 < np.mean(moved == 0) < 0.6  # Poisson(1): P(no notch) = e^-1 ~ 0.37
    single = along[(np.abs(along) > 0).sum(axis=-1) == 6]  # exactly one notch
    assert len(single) > 5
    np.testing.assert_allclose(np.abs(single).max(axis=-1), 3.0 * np.sin(np.pi * 2.5 / 6), rtol=1e-9)


def test_draws_are_per_sample_and_follow_the_documented_stream():
    c = _circles(n_rows=4)
    spec = Roughness()
    full = roughen_contours(c, spec, seed=5, sample_ids=[10, 11, 12, 13])
    one = roughen_contours(c[2:3], spec, seed=5, sample_ids=[12])
    np.testing.assert_array_equal(full[2:3], one)  # independent of the batch
    assert ROUGHNESS_STREAM == stream_code("roughness")
    other = roughen_contours(c[2:3], spec, seed=6, sample_ids=[12])
    assert not np.allclose(one, other)
    rng = derive_rng(5, ROUGHNESS_STREAM, 12)  # the first draw of the stream is the wander's white noise
    np.testing.assert_array_equal(rng.standard_normal((2, 200)), derive_rng(5, stream_code("roughness"), 12).standard_normal((2, 200)))


def test_augment_rows_appends_copies_or_replaces():
    c, j = _circles(n_rows=3), np.arange(3 * 19 * 3, dtype=float).reshape(3, 19, 3)
    c2, j2 = augment_rows(c, j, Roughness(copies=2), seed=0)
    assert c2.shape == (9,) + c.shape[1:] and j2.shape == (9, 19, 3)
    np.testing.assert_array_equal(c2[:3], c)
    np.testing.assert_array_equal(j2[3:6], j)
    np.testing.assert_array_equal(c2[3:6], roughen_contours(c, Roughness(copies=2), 0))
    np.testing.assert_array_equal(c2[6:9], roughen_contours(c, Roughness(copies=2), 1))
    c0, j0 = augment_rows(c, j, Roughness(copies=0), seed=0)
    assert c0.shape == c.shape and not np.allclose(c0, c)


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="amplitude_px"):
        Roughness(amplitude_px=-1.0)
    with pytest.raises(ValueError, match="correlation"):
        Roughness(correlation=0.0)
    with pytest.raises(ValueError, match="shape"):
        roughen_contours(np.zeros((3, 200, 2)), Roughness(), 0)
