"""What robust inference takes from each frame's last reweighting pass only, computed once at the end: the stature
(the "stature" joint frame) and, for hypotheses and the calibrated mixing, every component's weight and mean. The
references are the ways of measuring them in every pass."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from silpose.datagen.testing import synthetic_record
from silpose.model import posterior as posterior_module
from silpose.model.robust import loop
from silpose.model.shape_model import ShapeStructureModel
from silpose.shared.camera import default_rig


@pytest.fixture(scope="module")
def stature_model_and_frames():
    rig = default_rig()
    config = {"seed": 7, "rig": rig.to_dict(), "n_points": 40}
    recs = [synthetic_record(config, "train", i) for i in range(80)]
    contours = np.stack([r["contours"] for r in recs]).astype(np.float64)
    model = ShapeStructureModel(3, 4, n_init=1, max_iter=30, random_state=0).fit(
        contours[:60], np.stack([r["joints"] for r in recs[:60]]), rig=rig)
    test = contours[60:].copy()
    test += np.random.default_rng(1).normal(0.0, 1.0, test.shape)
    test[::3, :, 10:18] += 6.0  # outliers for the reweighting to cut
    present = np.ones(test.shape[:2], bool)
    present[::4, 1] = False
    return model, test, present


def test_each_frames_stature_is_measured_once_with_the_joints_of_measuring_every_pass(stature_model_and_frames,
                                                                                       monkeypatch):
    model, contours, present = stature_model_and_frames
    assert model.layout_.joint_frame == "stature"
    calls = []
    measure = posterior_module.estimate_stature
    monkeypatch.setattr(posterior_module, "estimate_stature", lambda *a, **k: calls.append(1) or measure(*a, **k))
    new = model.infer(contours, present, robust=True, hypotheses=3)
    once = len(calls)

    # the old way: every pass scales its own joints (stature=True), nothing is scaled at the end
    plain_infer = posterior_module.Posterior.infer
    monkeypatch.setattr(posterior_module.Posterior, "infer",
                        lambda self, *a, **k: plain_infer(self, *a, **{**k, "stature": True}))
    scale = posterior_module.Posterior.scale_to_stature

    def scale_in_passes_only(self, res, comp, *args):  # the loop's scaling at the end is not the old way's
        return scale(self, res, comp, *args) if sys._getframe(1).f_code.co_name == "assemble" else comp

    monkeypatch.setattr(posterior_module.Posterior, "scale_to_stature", scale_in_passes_only)
    calls.clear()
    old = model.infer(contours, present, robust=True, hypotheses=3)

    assert len(calls) > 3 * once  # the Gaussian passes and every reweighting pass measured it
    for field in ("joints", "joints_best", "joint_std"):
        np.testing.assert_array_equal(getattr(new, field), getattr(old, field), err_msg=field)
    np.testing.assert_array_equal(new.hypotheses.joints, old.hypotheses.joints)
    np.testing.assert_array_equal(new.contours_px, old.contours_px)
    # the joints are the walkers' own size, not the 1.75 m reference's
    height = new.joints[..., 2].max(axis=1) - new.joints[..., 2].min(axis=1)
    assert np.ptp(height) > 0.01


def test_hypotheses_come_from_every_component_while_the_passes_condition_only_those_that_matter(
        stature_model_and_frames, monkeypatch):
    """With hypotheses the passes condition each frame on the components within the gate and the last pass's
    contours once more on every component; the reference conditions every component in every pass (a gate that
    keeps them all). The same hypotheses, weights and joints (to rounding: the gate leaves out < e^-30)."""
    model, contours, present = stature_model_and_frames
    gated = []
    plain = loop.Posterior.infer

    def infer(self, inputs, s2, components=False, only=None, **kw):
        if only is not None:
            gated.append(int(np.asarray(only).sum()) < np.asarray(only).size)
        return plain(self, inputs, s2, components, only, **kw)

    monkeypatch.setattr(loop.Posterior, "infer", infer)
    new = model.infer(contours, present, robust=True, hypotheses=3)
    assert any(gated)  # some frame's pass left a component out
    monkeypatch.setattr(loop, "GATE_WEIGHT", -1.0)  # every component in every pass
    gated.clear()
    ref = model.infer(contours, present, robust=True, hypotheses=3)
    assert not any(gated)
    np.testing.assert_array_equal(new.hypotheses.probability.argsort(axis=1), ref.hypotheses.probability.argsort(axis=1))
    np.testing.assert_allclose(new.hypotheses.probability, ref.hypotheses.probability, rtol=0, atol=1e-9)
    np.testing.assert_allclose(new.hypotheses.joints, ref.hypotheses.joints, rtol=0, atol=1e-9)
    np.testing.assert_allclose(new.responsibilities, ref.responsibilities, rtol=0, atol=1e-9)
    np.testing.assert_allclose(new.joints, ref.joints, rtol=0, atol=1e-9)
