"""Limb swing of library frames (``[motion] limb_swing``): each arm turned about its shoulder and each leg
about its hip as a rigid chain (no Blender).

References are independent of :func:`swing_limbs`: rotations come from SciPy's ``Rotation.from_rotvec``, and
the swung pose's bone directions are compared with the unswung pose's own, turned by that rotation in the
body frame :func:`retarget_frame` builds from the (unchanged) hip line.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from silpose.datagen.motion.config import MotionConfigError, motion_from_dict
from silpose.datagen.motion.library import BUNDLED
from silpose.datagen.motion.mix import MIX_FIELDS, SWING_FIELDS, MixedMotion, prepare_library
from silpose.datagen.motion.retarget import LIMBS, heading_of, retarget_frame, rotation_from_vector, swing_limbs
from silpose.datagen.subjects import sample_subject
from silpose.datagen.walk import euler_matrix
from silpose.shared.seeds import derive_rng
from silpose.shared.skeleton import JOINT_NAMES, PARENTS

J = {n: i for i, n in enumerate(JOINT_NAMES)}


@lru_cache(maxsize=None)
def _worker(swing: float, deg: float = 60.0) -> dict:
    raw = {"source": "library", "procedural_walk": 0.2, "mirror": True, "limb_swing": swing, "limb_swing_deg": deg}
    return prepare_library(motion_from_dict(raw, BUNDLED, "t")).worker()


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_rotation_from_vector_is_scipys_rotvec():
    rng = np.random.default_rng(0)
    for v in [*rng.normal(size=(20, 3)), np.zeros(3), np.array([0.0, 0.0, np.pi])]:
        np.testing.assert_allclose(rotation_from_vector(v), Rotation.from_rotvec(v).as_matrix(), atol=1e-12)


def test_swung_limbs_turn_as_rigid_chains_about_their_pivots():
    m = MixedMotion.from_config(_worker(0.0), "train")
    clip = m.bvh.clips[3]
    pts = clip.points(int(clip.used[len(clip.used) // 2]), False)
    subject = sample_subject(np.random.default_rng(4), "train")
    swings = {"l_arm": np.array([0.0, 1.2, 0.3]), "r_leg": np.array([0.9, 0.0, -0.2])}
    Ja, _, yaw_a = retarget_frame(pts, subject)
    Jm, _, yaw_m = retarget_frame(swing_limbs(pts, swings), subject)
    assert yaw_m == pytest.approx(yaw_a, abs=1e-12)  # the hip line is not moved
    H = euler_matrix((0.0, 0.0, yaw_a))  # body frame: q = H^T (p - pelvis)
    turned = {"l_arm": ("l_elbow", "l_wrist"), "r_leg": ("r_knee", "r_ankle")}
    for limb, joints in turned.items():
        R = H.T @ Rotation.from_rotvec(swings[limb]).as_matrix() @ H
        for name in joints:
            c = J[name]
            d_a = _unit(Ja[c] - Ja[PARENTS[c]])
            d_m = _unit(Jm[c] - Jm[PARENTS[c]])
            np.testing.assert_allclose(d_m, R @ d_a, atol=1e-9)
    for name in ("r_elbow", "r_wrist", "l_knee", "l_ankle", "head", "neck"):  # the other limbs and the trunk stay
        np.testing.assert_allclose(Jm[J[name]], Ja[J[name]], atol=1e-9)
    assert swing_limbs(pts, {}) == pts


def test_limb_swing_leaves_the_first_draws_and_the_test_split_unchanged():
    plain, swung = _worker(0.0), _worker(0.5)
    for split in ("train", "test"):
        m0, m1 = MixedMotion.from_config(plain, split), MixedMotion.from_config(swung, split)
        assert m0.fields == MIX_FIELDS and m1.fields == MIX_FIELDS + SWING_FIELDS
        flags, library = [], []
        for i in range(200):
            p0, p1 = m0.draw(derive_rng(7, 0, 0, i, 0)), m1.draw(derive_rng(7, 0, 0, i, 0))
            assert {k: p1[k] for k in MIX_FIELDS} == p0
            vec = np.array([p1[k] for k in SWING_FIELDS]).reshape(len(LIMBS), 3)
            flags.append(bool(np.any(vec)))
            library.append(p0["clip"] > 0)
            assert np.all(np.linalg.norm(vec, axis=1) <= np.deg2rad(60.0) + 1e-12)
        share = np.mean(np.array(flags)[library])
        if split == "train":
            assert 0.35 < share < 0.65, share
            assert not np.any(np.array(flags)[~np.array(library)])  # the procedural walk is never swung
        else:
            assert share == 0.0


def test_swung_poses_are_people_on_the_floor_with_their_own_bones():
    m = MixedMotion.from_config(_worker(1.0, 120.0), "train")
    subject = sample_subject(np.random.default_rng(5), "train")
    n = 0
    for i in range(40):
        p = m.draw(derive_rng(7, 0, 0, i, 0))
        if not any(p[k] for k in SWING_FIELDS):
            continue
        pose = m.pose(subject, p)
        rest = m.pose(subject, {**p, **{k: 0.0 for k in SWING_FIELDS}})
        bones = np.linalg.norm(pose.joints[1:] - pose.joints[list(PARENTS[1:])], axis=1)
        np.testing.assert_allclose(bones, np.linalg.norm(rest.joints[1:] - rest.joints[list(PARENTS[1:])], axis=1),
                                   atol=1e-9)
        assert pose.joints[:, 2].min() > -0.05 and pose.joints[J["head_top"], 2] > pose.joints[0, 2]
        assert np.abs(pose.joints - rest.joints).max() > 0.01
        n += 1
    assert n > 30


@pytest.mark.parametrize("field,bad", [("limb_swing", 1.5), ("limb_swing", "some"), ("limb_swing_deg", 0),
                                       ("limb_swing_deg", 200), ("limb_swing_deg", True)])
def test_limb_swing_fields_are_checked(field, bad):
    with pytest.raises(MotionConfigError, match=field):
        motion_from_dict({"source": "library", field: bad}, BUNDLED, "cfg.toml")
