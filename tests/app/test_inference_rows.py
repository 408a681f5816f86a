"""silpose.app.inference.infer_rows: frames that lost every view get NaN rows, the others equal the model's
inference; a model without a rig cannot read a frames folder.

``infer_rows`` and ``merge_results`` keep every field of the model's result. The bug of issue 24: the merge listed
the result's fields by hand and dropped ``excursions_trimmed``, ``reindexed`` and ``robust_input_px``, so
``silpose infer --frames`` (which merges chunks) and ``silpose infer INPUT`` with a frame without a usable view
wrote empty ``views_trimmed`` / ``views_reindexed`` columns."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pyarrow.parquet as pq
import pytest

from silpose.app.errors import FramesInputError
from silpose.app.inference import TOP_K, InferOptions, infer_rows, merge_results
from silpose.app.inputs.frames_folder import open_frames
from silpose.app.writers import write_joints
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.shared.contours import extract_contour


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


N_POINTS = 200


def _figure(rng, shadow: int = 0) -> np.ndarray:
    """(N_POINTS, 2) px contour of a standing figure with random limb lengths; ``shadow`` px: a flat ellipse
    sideways at the feet (an excursion robust inference trims)."""
    m = np.zeros((240, 320), np.uint8)
    leg, arm = int(rng.integers(50, 66)), int(rng.integers(45, 60))
    cv2.circle(m, (160, 60), int(rng.integers(10, 14)), 1, -1)
    cv2.rectangle(m, (140, 72), (180, 140), 1, -1)
    cv2.rectangle(m, (143, 140), (156, 140 + leg), 1, -1)
    cv2.rectangle(m, (164, 140), (177, 140 + leg), 1, -1)
    cv2.rectangle(m, (128, 76), (139, 76 + arm), 1, -1)
    cv2.rectangle(m, (181, 76), (192, 76 + arm), 1, -1)
    if shadow:
        cv2.ellipse(m, (160 + shadow, 139 + leg), (shadow, 3), 0, 0, 360, 1, -1)
    return extract_contour(m, N_POINTS).points.astype(np.float64)


@pytest.fixture(scope="module")
def model_and_frames():
    """A one-view model of the figure; 8 frames: clean ones, a shadowed one (row 2) and one without a view (row 5)."""
    rng = np.random.default_rng(0)
    contours = np.stack([_figure(rng) for _ in range(100)])[:, None]
    joints = np.zeros((100, 19, 3))
    joints[:, :, 2] = np.linspace(0, 1, 19)[None] * (1 + 0.01 * rng.normal(size=(100, 1)))
    model = ShapeStructureModel(n_components=2, n_latent=4, structure_weight=1.0, n_init=1, random_state=0,
                                joint_frame="metres").fit(contours, joints)
    frames = np.stack([_figure(rng, shadow=25 if i == 2 else 0) for i in range(8)])[:, None]
    present = np.ones((8, 1), bool)
    present[5] = False
    frames[5] = np.nan
    return model, frames, present


def _fields(res) -> dict:
    """Every field of an InferenceResult that is set, hypotheses' arrays flattened in."""
    out = {}
    for f in dataclasses.fields(res):
        value = getattr(res, f.name)
        if dataclasses.is_dataclass(value):
            out.update({f"{f.name}.{g.name}": getattr(value, g.name) for g in dataclasses.fields(value)})
        elif value is not None:
            out[f.name] = value
    return out


OPTIONS = InferOptions(hypotheses=TOP_K, robust=True, untangle=True)  # what silpose infer runs


def test_a_frame_without_a_view_keeps_every_field_of_the_others(model_and_frames, tmp_path):
    model, frames, present = model_and_frames
    ok = np.flatnonzero(present.any(axis=1))
    ref = model.infer(frames[ok], present[ok], **OPTIONS.infer_kwargs())
    assert ref.excursions_trimmed[list(ok).index(2)].any()  # the shadow is trimmed: the flags are not all False
    res = infer_rows(model, frames, present, options=OPTIONS)
    got = _fields(res)
    for name, value in _fields(ref).items():
        if name == "views":
            assert got[name] == value
            continue
        assert name in got, f"infer_rows dropped {name}"
        np.testing.assert_array_equal(np.asarray(got[name])[ok], value, err_msg=name)
    assert not res.views_present[5].any() and np.isnan(res.joints[5]).all()
    assert not res.excursions_trimmed[5].any() and not res.reindexed[5].any()
    # and the joints file says which view was trimmed (the column was always empty)
    out = tmp_path / "joints.parquet"
    write_joints(out, np.array([f"f{i}" for i in range(8)]), res, ["cam0"])
    assert pq.read_table(out).column("views_trimmed").to_pylist()[2] == "cam0"


def test_merged_chunks_keep_every_field(model_and_frames):
    """``silpose infer --frames`` infers chunk by chunk and merges the chunks' results."""
    model, frames, present = model_and_frames
    chunks = [np.arange(0, 3), np.arange(3, 8)]
    parts = [infer_rows(model, frames[c], present[c], options=OPTIONS) for c in chunks]
    merged = merge_results(parts, chunks, 8)
    got = _fields(merged)
    for part, rows in zip(parts, chunks):
        for name, value in _fields(part).items():
            if name == "views":
                continue
            assert name in got, f"merge_results dropped {name}"
            np.testing.assert_array_equal(np.asarray(got[name])[rows], value, err_msg=name)
    assert merged.excursions_trimmed[2].any()
