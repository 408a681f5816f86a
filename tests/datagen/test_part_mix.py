"""Part mixing of library frames (``[motion] part_mix``): the upper body of one frame on the legs of
another (no Blender).

References are independent of :func:`combine_legs`: the mixed pose's upper-body joints are compared
with the first frame's own retargeted pose, and its leg bone directions with the second frame's,
both in the body frame that :func:`retarget_frame` builds from each pose's own hip line.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from silpose.datagen.motion.config import MotionConfigError, motion_from_dict
from silpose.datagen.motion.library import BUNDLED
from silpose.datagen.motion.mix import MIX_FIELDS, PART_FIELDS, MixedMotion, prepare_library
from silpose.datagen.motion.retarget import combine_legs, retarget_frame
from silpose.datagen.subjects import sample_subject
from silpose.shared.seeds import derive_rng
from silpose.shared.skeleton import JOINT_NAMES, PARENTS

J = {n: i for i, n in enumerate(JOINT_NAMES)}
UPPER = [J[n] for n in ("spine", "neck", "head", "head_top", "l_shoulder", "l_elbow", "l_wrist",
                        "r_shoulder", "r_elbow", "r_wrist")]
LEGS = [J[f"{s}_{n}"] for s in "lr" for n in ("knee", "ankle", "toe")]


@lru_cache(maxsize=None)
def _worker(part_mix: float) -> dict:
    raw = {"source": "library", "procedural_walk": 0.2, "mirror": True, "part_mix": part_mix}
    return prepare_library(motion_from_dict(raw, BUNDLED, "t")).worker()


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_mixed_pose_has_the_first_frames_upper_body_and_the_second_frames_legs():
    m = MixedMotion.from_config(_worker(0.0), "train")
    subject = sample_subject(np.random.default_rng(3), "train")
    a, b = m.bvh.clips[0], m.bvh.clips[-1]  # two different clips (different subjects' motions)
    upper = a.points(int(a.used[len(a.used) // 2]), False)
    lower = b.points(int(b.used[len(b.used) // 3]), True)
    Ja, _, _ = retarget_frame(upper, subject)
    Jb, _, _ = retarget_frame(lower, subject)
    Jm, _, _ = retarget_frame(combine_legs(upper, lower), subject)
    # the body frame follows the hip line, which the mix turns to the upper frame's heading
    np.testing.assert_allclose(Jm[UPPER] - Jm[0], Ja[UPPER] - Ja[0], atol=1e-9)
    legs = [c for c in LEGS if JOINT_NAMES[c] in lower]  # a clip without toes: the foot follows the shank's frame
    assert len(legs) >= 4
    legs_m = _unit(Jm[legs] - Jm[[PARENTS[c] for c in legs]])
    legs_b = _unit(Jb[legs] - Jb[[PARENTS[c] for c in legs]])
    np.testing.assert_allclose(legs_m, legs_b, atol=1e-9)
    assert np.abs(Jm[LEGS] - Ja[LEGS]).max() > 0.05  # the legs did change
    same = combine_legs(upper, upper)
    for role, p in upper.items():
        np.testing.assert_allclose(same[role], p, atol=1e-12)


def test_part_mix_leaves_the_first_draws_and_the_test_split_unchanged():
    plain, mixed = _worker(0.0), _worker(0.5)
    for split in ("train", "test"):
        m0, m1 = MixedMotion.from_config(plain, split), MixedMotion.from_config(mixed, split)
        assert m0.fields == MIX_FIELDS and m1.fields == MIX_FIELDS + PART_FIELDS
        legs = []
        for i in range(200):
            p0, p1 = m0.draw(derive_rng(7, 0, 0, i, 0)), m1.draw(derive_rng(7, 0, 0, i, 0))
            assert {k: p1[k] for k in MIX_FIELDS} == p0
            legs.append(p1["legs_clip"])
            if p1["legs_clip"] >= 0:
                assert p1["clip"] > 0 and mixed["clips"][int(p1["legs_clip"]) - 1]["split"] == "train"
        library = [i for i in range(200) if m0.draw(derive_rng(7, 0, 0, i, 0))["clip"] > 0]
        share = np.mean([legs[i] >= 0 for i in library])
        if split == "train":
            assert 0.35 < share < 0.65, share
        else:
            assert share == 0.0


def test_part_mixed_poses_are_people_on_the_floor():
    m = MixedMotion.from_config(_worker(1.0), "train")
    subject = sample_subject(np.random.default_rng(5), "train")
    n = 0
    for i in range(40):
        p = m.draw(derive_rng(7, 0, 0, i, 0))
        if p["legs_clip"] < 0:
            continue
        pose = m.pose(subject, p)
        bones = np.linalg.norm(pose.joints[1:] - pose.joints[list(PARENTS[1:])], axis=1)
        rest = m.pose(subject, {**p, "legs_clip": -1.0})
        np.testing.assert_allclose(bones, np.linalg.norm(rest.joints[1:] - rest.joints[list(PARENTS[1:])], axis=1),
                                   atol=1e-9)  # the subject's own bone lengths either way
        assert pose.joints[:, 2].min() > -0.05 and pose.joints[J["head_top"], 2] > pose.joints[0, 2]
        n += 1
    assert n > 30


def test_part_mix_must_be_a_share():
    for bad in (1.5, -0.1, True, "half"):
        with pytest.raises(MotionConfigError, match="part_mix"):
            motion_from_dict({"source": "library", "part_mix": bad}, BUNDLED, "cfg.toml")
