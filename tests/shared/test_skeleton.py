"""Tests of the 19-joint skeleton tables in silpose.shared.skeleton."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.shared.skeleton import (
    BONES,
    JOINT_INDEX,
    JOINT_NAMES,
    LEFT_RIGHT_PAIRS,
    N_JOINTS,
    PARENTS,
    ROOT,
    TERMINAL_JOINTS,
    mirror_indices,
    root_relative,
)


def test_names_are_unique_and_indexed():
    assert N_JOINTS == 19 == len(JOINT_NAMES) == len(PARENTS)
    assert len(set(JOINT_NAMES)) == N_JOINTS
    assert all(JOINT_NAMES[i] == n for n, i in JOINT_INDEX.items())


def test_parents_form_a_tree_rooted_at_the_pelvis():
    assert JOINT_NAMES[ROOT] == "pelvis"
    assert [i for i, p in enumerate(PARENTS) if p < 0] == [ROOT]
    for j in range(N_JOINTS):
        seen, k = set(), j
        while PARENTS[k] >= 0:  # walk up: must reach the root without revisiting a joint
            assert k not in seen, f"cycle through {JOINT_NAMES[k]}"
            seen.add(k)
            assert 0 <= PARENTS[k] < N_JOINTS
            k = PARENTS[k]
        assert k == ROOT
    # Parents come before their children, so a single forward pass can do forward kinematics.
    assert all(p < c for c, p in enumerate(PARENTS) if p >= 0)
    assert len(BONES) == N_JOINTS - 1
    assert sorted(BONES) == sorted((PARENTS[c], c) for c in range(N_JOINTS) if c != ROOT)


def test_left_right_pairs_mirror():
    assert len(LEFT_RIGHT_PAIRS) == 7
    paired = [j for pair in LEFT_RIGHT_PAIRS for j in pair]
    assert len(set(paired)) == len(paired)
    for left, right in LEFT_RIGHT_PAIRS:
        assert JOINT_NAMES[left].startswith("l_") and JOINT_NAMES[right] == "r_" + JOINT_NAMES[left][2:]
    # Every name with a side has its partner; unpaired joints lie on the midline.
    sided = {n for n in JOINT_NAMES if n[:2] in ("l_", "r_")}
    assert sided == {JOINT_NAMES[j] for j in paired}
    perm = mirror_indices()
    assert np.array_equal(perm[perm], np.arange(N_JOINTS))  # an involution
    # Mirroring commutes with the parent table: the mirror of my parent is my mirror's parent.
    for j in range(N_JOINTS):
        p = PARENTS[j]
        assert PARENTS[perm[j]] == (perm[p] if p >= 0 else -1)


def test_terminal_joints_are_the_chain_ends():
    leaves = [j for j in range(N_JOINTS) if all(p != j for p in PARENTS)]
    assert sorted(TERMINAL_JOINTS) == leaves
    assert {JOINT_NAMES[j] for j in TERMINAL_JOINTS} == {"head_top", "l_wrist", "r_wrist", "l_toe", "r_toe"}


def test_root_relative():
    rng = np.random.default_rng(3)
    joints = rng.normal(size=(5, 2, N_JOINTS, 3))
    rel = root_relative(joints)
    np.testing.assert_array_equal(rel[..., ROOT, :], 0.0)
    for j in range(N_JOINTS):
        np.testing.assert_allclose(rel[..., j, :], joints[..., j, :] - joints[..., ROOT, :])
    with pytest.raises(ValueError, match="19, 3"):
        root_relative(np.zeros((18, 3)))
