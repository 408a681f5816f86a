"""Joint maps read off skeleton names (silpose.datagen.motion.name_match) for tools no built-in map names.

Reference: the roles labelled by hand for each naming convention below (the names the tools are known to
write), on the test skeleton's hierarchy (silpose.datagen.testing.SYNTH_SKELETON).
"""

from __future__ import annotations

import pytest

from silpose.datagen.motion.joint_maps import REQUIRED_ROLES, JointMapError, resolve_map
from silpose.datagen.motion.name_match import match_joint_map, split_name
from silpose.datagen.testing import SYNTH_SKELETON

PARENTS = [row[2] for row in SYNTH_SKELETON]
#: SYNTH_SKELETON index of every role (its clavicles, 5 and 9, and spine joints, 1 and 2, are no role).
ROLE_INDEX = {"pelvis": 0, "neck": 3, "head": 4, "l_shoulder": 6, "l_elbow": 7, "l_wrist": 8, "r_shoulder": 10,
              "r_elbow": 11, "r_wrist": 12, "l_hip": 13, "l_knee": 14, "l_ankle": 15, "l_toe": 16, "r_hip": 17,
              "r_knee": 18, "r_ankle": 19, "r_toe": 20}

#: Each convention's names in SYNTH_SKELETON order (pelvis, spine, chest, neck, head, left clavicle, upper arm,
#: forearm, hand, right ..., left thigh, shin, foot, toe, right ...).
CONVENTIONS = {
    "unreal": ["pelvis", "spine_01", "spine_02", "neck_01", "head", "clavicle_l", "upperarm_l", "lowerarm_l",
               "hand_l", "clavicle_r", "upperarm_r", "lowerarm_r", "hand_r", "thigh_l", "calf_l", "foot_l", "ball_l",
               "thigh_r", "calf_r", "foot_r", "ball_r"],
    "biped": ["Bip01 Pelvis", "Bip01 Spine", "Bip01 Spine1", "Bip01 Neck", "Bip01 Head", "Bip01 L Clavicle",
              "Bip01 L UpperArm", "Bip01 L Forearm", "Bip01 L Hand", "Bip01 R Clavicle", "Bip01 R UpperArm",
              "Bip01 R Forearm", "Bip01 R Hand", "Bip01 L Thigh", "Bip01 L Calf", "Bip01 L Foot", "Bip01 L Toe0",
              "Bip01 R Thigh", "Bip01 R Calf", "Bip01 R Foot", "Bip01 R Toe0"],
    "motive": ["Hip", "Ab", "Chest", "Neck", "Head", "LShoulder", "LUArm", "LFArm", "LHand", "RShoulder", "RUArm",
               "RFArm", "RHand", "LThigh", "LShin", "LFoot", "LToe", "RThigh", "RShin", "RFoot", "RToe"],
    "kinect": ["SpineBase", "SpineMid", "SpineShoulder", "Neck", "Head", "CollarLeft", "ShoulderLeft", "ElbowLeft",
               "WristLeft", "CollarRight", "ShoulderRight", "ElbowRight", "WristRight", "HipLeft", "KneeLeft",
               "AnkleLeft", "FootLeft", "HipRight", "KneeRight", "AnkleRight", "FootRight"],
    "namespaced": [f"Character1_{n}" for n in (
        "Hips", "Spine", "Spine1", "Neck", "Head", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
        "RightShoulder", "RightArm", "RightForeArm", "RightHand", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
        "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase")],
    "blender-rigify": ["torso", "spine.001", "chest", "neck", "head", "shoulder.L", "upper_arm.L", "forearm.L",
                       "hand.L", "shoulder.R", "upper_arm.R", "forearm.R", "hand.R", "thigh.L", "shin.L", "foot.L",
                       "toe.L", "thigh.R", "shin.R", "foot.R", "toe.R"],
}


@pytest.mark.parametrize("convention", sorted(CONVENTIONS))
def test_every_role_found_for_each_convention(convention):
    names = CONVENTIONS[convention]
    assert match_joint_map(names, PARENTS) == {role: names[j] for role, j in ROLE_INDEX.items()}


def test_twist_joints_between_limb_joints_are_skipped():
    """upperarm -> upperarm_twist -> lowerarm: the shoulder is the upper arm, not its twist joint; leaf twist and
    extra joints take no role."""
    names = list(CONVENTIONS["unreal"]) + ["upperarm_twist_01_l", "calf_twist_01_l", "ik_foot_root"]
    parents = list(PARENTS) + [6, 14, -1]
    parents[7] = len(names) - 3  # lowerarm_l now hangs below upperarm_twist_01_l
    table = match_joint_map(names, parents)
    assert table["l_shoulder"] == "upperarm_l" and table["l_elbow"] == "lowerarm_l"
    assert table["l_knee"] == "calf_l" and set(table.values()) <= set(CONVENTIONS["unreal"])


def test_auto_uses_the_matched_map_and_names_unmatched_roles():
    names = CONVENTIONS["motive"]
    heads = [[0.0, 0.0, 0.0]] * len(names)
    tails = [[0.0, 0.0, 0.1]] * len(names)
    jm = resolve_map(names, PARENTS, heads, tails, "auto", "take.bvh")
    assert jm.name == "matched"
    assert {r: jm.index[r] for r in REQUIRED_ROLES} == {r: ROLE_INDEX[r] for r in REQUIRED_ROLES}
    assert jm.spine_chain[0] == ROLE_INDEX["neck"] or ROLE_INDEX["neck"] in jm.spine_chain
    no_hands = [n.replace("Hand", "Paw") for n in names]
    with pytest.raises(JointMapError) as err:
        resolve_map(no_hands, PARENTS, heads, tails, "auto", "take.bvh")
    msg = str(err.value)
    assert msg.startswith("take.bvh: joint names match no built-in map") and "reads as silpose l_wrist, r_wrist;" in msg
    assert "\n" not in msg


@pytest.mark.parametrize("name, side, part", [
    ("LeftUpLeg", "l", "upleg"), ("lThigh", "l", "thigh"), ("thigh_l", "l", "thigh"), ("Bip01 L Thigh", "l", "thigh"),
    ("mixamorig:RightForeArm", "r", "forearm"), ("UpperArm_R", "r", "upperarm"), ("LUArm", "l", "uarm"),
    ("KneeLeft", "l", "knee"), ("Hips", "", "hips"), ("LowerBack", "", "lowerback"), ("Left Knee", "l", "knee"),
    ("RShin", "r", "shin"), ("forearm.L", "l", "forearm"),
])
def test_split_name(name, side, part):
    assert split_name(name) == (side, part)
