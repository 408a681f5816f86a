"""A joint map read off a skeleton's names and hierarchy, for BVH files no built-in map fits.

Motion-capture tools name the same joints in many ways: ``LeftLeg`` (CMU, Xsens, Perception Neuron),
``calf_l`` (Unreal), ``Bip01 L Calf`` (3ds Max Biped), ``LShin`` (OptiTrack Motive), ``KneeLeft``
(Kinect), ``lShin`` (DAZ), ``LowerLeg_L`` (Bandai Namco), with namespaces (``mixamorig:``,
``Character1_``). :func:`match_joint_map` reads each name as a *side* and a *part*, and leans on the
hierarchy for what names leave open, so the clavicle is never taken for the shoulder nor a twist bone
for a limb joint:

1. side: a token ``Left``/``L``/``l`` (or ``Right``/``R``/``r``) at either end of the name, split at
   separators (``_ . - : space``) and at case changes (``LeftUpLeg``, ``lThigh``, ``LUArm``, ``thigh_l``);
   the part is what remains, lower case, without separators (``upleg``, ``thigh``, ``uarm``);
2. per side, the **knee** is the joint whose part is a lower-leg word (:data:`KNEE_PARTS`) nearest the
   root, and the **elbow** the one with a forearm word (:data:`ELBOW_PARTS`); the **hip** and the
   **shoulder** are their parents (the joint where the thigh and the upper arm start), skipping twist
   and roll joints;
3. the **ankle** and **wrist** are the nearest descendants of knee and elbow with a foot / hand word
   (:data:`ANKLE_PARTS`, :data:`WRIST_PARTS`); the optional **toe** is the nearest descendant of the
   ankle with a toe or foot word;
4. the **pelvis** is the lowest common ancestor of the two hips; the **neck** the joint nearest the
   pelvis, on the way up to the head, whose part starts with ``neck``; the **head** a joint whose part
   is ``head`` below the neck; the optional **head_top** a child of the head with a head-end word.

The result is a role -> joint-name table like :data:`silpose.datagen.motion.joint_maps.BUILTIN_MAPS`'s,
checked by the same resolution (:func:`silpose.datagen.motion.joint_maps.resolve_map`), which names the
required roles left unmatched.
"""

from __future__ import annotations

import re
from typing import Sequence

KNEE_PARTS = frozenset({"leg", "knee", "shin", "calf", "lowerleg", "lowleg", "loleg", "lleg", "tibia", "shank"})
ELBOW_PARTS = frozenset({"forearm", "elbow", "lowerarm", "lowarm", "loarm", "farm", "radius"})
ANKLE_PARTS = frozenset({"foot", "ankle"})
WRIST_PARTS = frozenset({"hand", "wrist"})
TOE_PARTS = frozenset({"toe", "toes", "toebase", "toe0", "ball", "foot"})
HEAD_TOP_PARTS = frozenset({"headtop", "headend", "headtopend", "headnub", "headsite", "headtip"})
#: Parts of joints that sit between two limb joints without being one (skipped going up to hip/shoulder).
PASS_THROUGH = ("twist", "roll", "share")

_WORDS = re.compile(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+")
_SIDE_WORDS = {"left": "l", "l": "l", "right": "r", "r": "r"}


def name_words(name: str) -> list[str]:
    """The words of a joint name without its namespace: split at separators and case changes."""
    base = name.rsplit(":", 1)[-1]
    glued = re.fullmatch(r"([LR])([A-Z][A-Za-z0-9]*)", base)  # "LUArm", "RHand": a side letter glued on
    if glued and not glued.group(2).isupper():
        return [glued.group(1), glued.group(2)]
    return [w for chunk in re.split(r"[\s_.\-]+", base) for w in _WORDS.findall(chunk)]


def split_words(words: Sequence[str]) -> tuple[str, str]:
    """(side ``"l"``/``"r"``/``""``, part) of a joint name's words (module docstring, step 1)."""
    low = [w.lower() for w in words]
    if len(low) >= 2 and low[0] in _SIDE_WORDS:
        return _SIDE_WORDS[low[0]], "".join(low[1:])
    if len(low) >= 2 and low[-1] in _SIDE_WORDS:
        return _SIDE_WORDS[low[-1]], "".join(low[:-1])
    inner = [i for i, w in enumerate(low) if w in _SIDE_WORDS]
    if len(inner) == 1:  # "Character1_LeftUpLeg" after a prefix the skeleton does not share
        i = inner[0]
        return _SIDE_WORDS[low[i]], "".join(low[i + 1:])
    return "", "".join(low)


def split_name(name: str) -> tuple[str, str]:
    """(side, part) of one joint name (module docstring, step 1)."""
    return split_words(name_words(name))


def split_names(names: Sequence[str]) -> list[tuple[str, str]]:
    """(side, part) of every joint of a skeleton, after dropping the words all its names start with
    (a rig prefix such as ``Bip01``, ``CC_Base``, ``Character1``)."""
    words = [name_words(n) for n in names]
    k = 0
    if len(words) > 1:
        while (all(len(w) > k and w[k] == words[0][k] for w in words) and words[0][k].lower() not in _SIDE_WORDS
               and sum(len(w) == k + 1 for w in words) <= 1):  # at most the rig's root ("Bip01") is used up
            k += 1
    return [split_words(w[k:]) for w in words]


def _ancestors(parents: Sequence[int], j: int) -> list[int]:
    out = []
    while parents[j] >= 0:
        j = parents[j]
        out.append(j)
    return out


def _depth(parents: Sequence[int], j: int) -> int:
    return len(_ancestors(parents, j))


def _nearest_descendant(parents: Sequence[int], top: int, candidates: Sequence[int]) -> int:
    """The candidate below ``top`` with the fewest joints between them, or -1."""
    below = [(len(_ancestors(parents, c)), c) for c in candidates if top in _ancestors(parents, c)]
    return min(below)[1] if below else -1


def _limb_parent(parents: Sequence[int], parts: Sequence[str], j: int) -> int:
    """The parent of ``j``, skipping twist/roll joints (module docstring, step 2)."""
    p = parents[j]
    while p >= 0 and any(w in parts[p] for w in PASS_THROUGH):
        p = parents[p]
    return p


def match_joint_map(names: Sequence[str], parents: Sequence[int]) -> dict[str, str]:
    """Role -> joint name for every role matched in the skeleton ``names`` (J,) with ``parents`` (J,)
    (-1 for a root); roles left unmatched are absent (the caller checks the required ones)."""
    sides, parts = zip(*split_names(names)) if names else ((), ())
    index: dict[str, int] = {}

    def first(cands: list[int]) -> int:
        return min(cands, key=lambda j: (_depth(parents, j), j)) if cands else -1

    for s in ("l", "r"):
        mine = [j for j in range(len(names)) if sides[j] == s]
        knee = first([j for j in mine if parts[j] in KNEE_PARTS])
        elbow = first([j for j in mine if parts[j] in ELBOW_PARTS])
        found = {"knee": knee, "elbow": elbow}
        found["hip"] = _limb_parent(parents, parts, knee) if knee >= 0 else -1
        found["shoulder"] = _limb_parent(parents, parts, elbow) if elbow >= 0 else -1
        found["ankle"] = _nearest_descendant(parents, knee, [j for j in mine if parts[j] in ANKLE_PARTS]) if knee >= 0 else -1
        found["wrist"] = _nearest_descendant(parents, elbow, [j for j in mine if parts[j] in WRIST_PARTS]) if elbow >= 0 else -1
        if found["ankle"] >= 0:
            toe = _nearest_descendant(parents, found["ankle"],
                                      [j for j in range(len(names)) if parts[j] in TOE_PARTS or parts[j].startswith("toe")])
            if toe >= 0:
                found["toe"] = toe
        for role, j in found.items():
            if j >= 0:
                index[f"{s}_{role}"] = j
    if "l_hip" in index and "r_hip" in index:
        left = [index["l_hip"], *_ancestors(parents, index["l_hip"])]
        right = set(_ancestors(parents, index["r_hip"])) | {index["r_hip"]}
        common = [j for j in left[1:] if j in right]
        if common:
            index["pelvis"] = common[0]
    if "pelvis" in index:
        necks = [j for j in range(len(names)) if not sides[j] and parts[j].startswith("neck")
                 and index["pelvis"] in _ancestors(parents, j)]
        neck = first(necks)
        if neck >= 0:
            index["neck"] = neck
            head = _nearest_descendant(parents, neck, [j for j in range(len(names)) if parts[j] == "head"])
            if head >= 0:
                index["head"] = head
                top = [j for j in range(len(names)) if parents[j] == head and parts[j] in HEAD_TOP_PARTS]
                if top:
                    index["head_top"] = top[0]
    return {role: names[j] for role, j in index.items()}
