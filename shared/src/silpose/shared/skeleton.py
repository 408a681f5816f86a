"""The 19-joint skeleton shared by every package, as plain data.

Joint positions are in metres. The *structure target* of the model is the joints
relative to the pelvis (root) in world orientation (docs/conventions.md, "Skeleton"): ``joints - joints[PELVIS]``.
"""

from __future__ import annotations

import numpy as np

JOINT_NAMES: tuple[str, ...] = (
    "pelvis",  # 0, root
    "spine",  # 1
    "neck",  # 2
    "head",  # 3
    "head_top",  # 4
    "l_shoulder",  # 5
    "l_elbow",  # 6
    "l_wrist",  # 7
    "r_shoulder",  # 8
    "r_elbow",  # 9
    "r_wrist",  # 10
    "l_hip",  # 11
    "l_knee",  # 12
    "l_ankle",  # 13
    "l_toe",  # 14
    "r_hip",  # 15
    "r_knee",  # 16
    "r_ankle",  # 17
    "r_toe",  # 18
)
N_JOINTS = len(JOINT_NAMES)
JOINT_INDEX: dict[str, int] = {name: i for i, name in enumerate(JOINT_NAMES)}

#: Parent of each joint (-1 for the root), in ``JOINT_NAMES`` order.
PARENTS: tuple[int, ...] = (
    -1,  # pelvis
    0,  # spine <- pelvis
    1,  # neck <- spine
    2,  # head <- neck
    3,  # head_top <- head
    2,  # l_shoulder <- neck
    5,  # l_elbow
    6,  # l_wrist
    2,  # r_shoulder <- neck
    8,  # r_elbow
    9,  # r_wrist
    0,  # l_hip <- pelvis
    11,  # l_knee
    12,  # l_ankle
    13,  # l_toe
    0,  # r_hip <- pelvis
    15,  # r_knee
    16,  # r_ankle
    17,  # r_toe
)

#: Left/right joint pairs (index of left, index of right).
LEFT_RIGHT_PAIRS: tuple[tuple[int, int], ...] = tuple(
    (JOINT_INDEX["l_" + n], JOINT_INDEX["r_" + n])
    for n in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle", "toe")
)

#: Joints at the end of a chain; the body's end caps can put them ~2 px outside a silhouette.
TERMINAL_JOINTS: tuple[int, ...] = tuple(
    i for i in range(N_JOINTS) if i not in set(PARENTS)
)
ROOT = JOINT_INDEX["pelvis"]

#: Bones as (parent, child) index pairs, for drawing stick figures.
BONES: tuple[tuple[int, int], ...] = tuple((p, c) for c, p in enumerate(PARENTS) if p >= 0)


def root_relative(joints: np.ndarray) -> np.ndarray:
    """Joints relative to the pelvis, world orientation.

    Args:
        joints: (..., 19, 3) positions in metres.
    Returns:
        (..., 19, 3) array with the pelvis at the origin.
    """
    joints = np.asarray(joints)
    if joints.shape[-2:] != (N_JOINTS, 3):
        raise ValueError(f"joints must have shape (..., {N_JOINTS}, 3), got {joints.shape}")
    return joints - joints[..., ROOT : ROOT + 1, :]


def mirror_indices() -> np.ndarray:
    """(19,) permutation that swaps every left joint with its right partner."""
    perm = np.arange(N_JOINTS)
    for left, right in LEFT_RIGHT_PAIRS:
        perm[left], perm[right] = right, left
    return perm
