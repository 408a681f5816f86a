"""Calibrated weights of the posterior mean (silpose.model.mixing): tempered responsibilities and heading votes."""

import numpy as np
import pytest

from silpose.model.hypotheses import heading, is_flip, single_answer, top_hypotheses
from silpose.model.mixing import (Mixing, agreeing_choice, calibrate_mixing, mixed_joints, mixture_terms,
                                  vote_agreement)
from silpose.model.persistence import load_model, save_model
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.shared.camera import default_rig
from silpose.shared.metrics import pose_error_cm
from silpose.shared.skeleton import JOINT_INDEX, N_JOINTS, mirror_indices


@pytest.fixture(scope="module")
def fitted():
    data = make_linear_shapes(160, n_views=4, n_points=10, seed=7, n_clusters=3)
    model = ShapeStructureModel(3, 3, structure_weight=1.5, noise_variance=2e-3, n_init=1, random_state=0,
                                max_iter=30, joint_frame="metres")
    model.fit(data.contours[:120], data.joints[:120], rig=default_rig())
    return model, data


def _walker_facing_x() -> np.ndarray:
    """(19, 3) root-relative joints of a person facing +x (left = +y), left knee bent forward."""
    j = np.zeros((N_JOINTS, 3))
    up = {"spine": 0.2, "neck": 0.5, "head": 0.6, "head_top": 0.7}
    for name, z in up.items():
        j[JOINT_INDEX[name], 2] = z
    for side, y in (("l", 0.1), ("r", -0.1)):
        j[JOINT_INDEX[f"{side}_hip"]] = (0.0, y, 0.0)
        j[JOINT_INDEX[f"{side}_knee"]] = (0.15 if side == "l" else 0.0, y, -0.45)
        j[JOINT_INDEX[f"{side}_ankle"]] = (0.0, y, -0.9)
        j[JOINT_INDEX[f"{side}_toe"]] = (0.1, y, -0.95)
        j[JOINT_INDEX[f"{side}_shoulder"]] = (0.0, 2 * y, 0.5)
        j[JOINT_INDEX[f"{side}_elbow"]] = (0.0, 2 * y, 0.25)
        j[JOINT_INDEX[f"{side}_wrist"]] = (0.1, 2 * y, 0.05)
    return j


def test_temperature_one_without_votes_is_the_posterior_mean(fitted):
    model, data = fitted
    c = data.contours[120:]
    present = np.ones((len(c), 4), bool)
    present[::2, 1] = False
    plain = model.infer(c, present, mixing=False)
    comp, resp, _ = mixture_terms(model, c, present, robust=False)
    # the mixture's own posterior mean (the conditioning's output product) against the weighted component means
    np.testing.assert_allclose(mixed_joints(comp, resp, 1.0), plain.joints, atol=1e-9)
    same = model.infer(c, present, mixing=Mixing(temperatures={3: 1.0, 4: 1.0}, vote_weight=0.0))
    np.testing.assert_allclose(same.joints, plain.joints, atol=1e-9)


def test_votes_choose_the_mirrored_pose_when_the_views_see_it():
    facing = _walker_facing_x()
    # the front/back mirror: reflect along the forward axis (x), then swap left and right -> faces -x
    mirrored = (facing * np.array([-1.0, 1.0, 1.0]))[mirror_indices()]
    assert abs(abs(heading(facing) - heading(mirrored)) - np.pi) < 1e-9
    comp = np.stack([facing, mirrored])[None]  # (1, 2, 19, 3): the wrong-facing component is the likelier
    resp = np.array([[0.99, 0.01]])
    votes = np.full((1, 6), heading(mirrored))  # every pair of views sees the person facing -x
    agree = vote_agreement(comp, votes)
    np.testing.assert_allclose(agree, [[-1.0, 1.0]], atol=1e-12)
    assert is_flip(mixed_joints(comp, resp, 1.0), mirrored[None])[0]  # the mixture alone follows the likelier
    beta = 10.0
    out = mixed_joints(comp, resp, 1.0, agree, beta)
    w = 0.01 * np.exp(beta) / (0.99 * np.exp(-beta) + 0.01 * np.exp(beta))  # by hand
    np.testing.assert_allclose(out[0], w * mirrored + (1 - w) * facing, atol=1e-12)
    assert not is_flip(out, mirrored[None])[0] and pose_error_cm(out, mirrored[None])[0] < 0.1
    # silpose infer's single answer keeps the voted pose: the chosen hypothesis is the one facing its way
    hyp = top_hypotheses(comp, resp, 2)
    assert hyp.component[0, 0] == 0 and is_flip(single_answer(out, hyp), mirrored[None])[0]  # slot 0 would undo it
    hyp.chosen = agreeing_choice(hyp, out)
    assert hyp.chosen[0] == 1
    np.testing.assert_array_equal(single_answer(out, hyp), out)
    # a high temperature spreads the weight evenly: the average of the two
    np.testing.assert_allclose(mixed_joints(comp, resp, 1e9)[0], 0.5 * (facing + mirrored), atol=1e-6)
    # a frame without votes keeps the mixture's weights; a component not evaluated (NaN) gets none
    np.testing.assert_allclose(vote_agreement(comp, np.full((1, 6), np.nan)), 0.0)
    comp_nan = comp.copy()
    comp_nan[0, 0] = np.nan
    np.testing.assert_allclose(mixed_joints(comp_nan, resp, 1.0)[0], mirrored, atol=1e-12)


def test_mixing_dict_round_trip_and_errors():
    m = Mixing(temperatures={1: 7.0, 4: 10.0}, vote_weight=2.0, n_inputs=160, errors_cm={4: [15.7, 14.8]})
    back = Mixing.from_dict(m.to_dict())
    assert back.temperatures == {1: 7.0, 4: 10.0} and back.vote_weight == 2.0 and back.errors_cm == {4: [15.7, 14.8]}
    np.testing.assert_array_equal(back.temperature(np.array([1, 2, 4])), [7.0, 1.0, 10.0])
    with pytest.raises(ValueError, match=r"model\.npz.*>= 1"):
        Mixing.from_dict({"temperatures": {"4": 0.5}, "vote_weight": 0.0}, source="model.npz")
    with pytest.raises(ValueError, match=r"model\.npz: field 'vote_weight'"):
        Mixing.from_dict({"temperatures": {}}, source="model.npz")


def test_calibration_is_chosen_on_held_out_rows_saved_and_used(fitted, tmp_path):
    model, data = fitted
    c, j = data.contours[120:150], data.joints[120:150]
    mix = calibrate_mixing(model, c, j, robust=False, temperatures=(1.0, 3.0), vote_weights=(0.0, 5.0))
    assert set(mix.temperatures) == {1, 2, 3, 4} and mix.vote_weight in (0.0, 5.0) and mix.n_inputs == 30
    # the recorded errors are those infer gives with and without the calibration (all 4 views)
    plain = pose_error_cm(model.infer(c, mixing=False).joints, j).mean()
    tuned = pose_error_cm(model.infer(c, mixing=mix).joints, j).mean()
    np.testing.assert_allclose(mix.errors_cm[4], [plain, tuned], rtol=1e-9)
    assert tuned <= plain + 1e-12  # T = 1 without votes is on the grid
    model.mixing_ = mix
    try:
        loaded = load_model(save_model(tmp_path / "m.npz", model))
        assert loaded.mixing_.to_dict() == mix.to_dict()
        present = np.ones((len(c), 4), bool)
        present[:, 2] = False
        np.testing.assert_array_equal(loaded.infer(c, present, robust=True).joints,
                                      model.infer(c, present, robust=True, mixing=mix).joints)
    finally:
        model.mixing_ = None
