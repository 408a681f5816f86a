"""Joint maps: which BVH joint stands for which silpose joint (pure data and checks, no bpy).

A map gives, for each *role*, the name of the BVH joint whose position (the head of its bone
after Blender's import) is that silpose joint. Roles are the silpose joints a clip must supply:

- required: ``pelvis``, ``neck``, ``head``, and per side (``l_``/``r_``) ``shoulder`` (the
  shoulder joint where the upper arm starts, not the clavicle), ``elbow``, ``wrist``, ``hip``,
  ``knee``, ``ankle``;
- optional: ``l_toe``/``r_toe`` (without them the foot keeps the subject's default orientation
  relative to the shank) and ``head_top`` (without it the head top is taken from the end of the
  BVH head bone when that bone points the way the neck-to-head direction does in the clip's rest
  pose, else it continues the neck-to-head direction).

silpose's ``spine`` joint is not mapped: it is placed on the clip's spine chain (the BVH joints
between ``pelvis`` and ``neck``, however many there are) at the subject's own fraction of the
torso (:mod:`.retarget`). Every other BVH joint (clavicles, extra spine and neck joints, fingers,
toes beyond the mapped one, props) is ignored.

Built-in maps (:data:`BUILTIN_MAPS`), chosen with ``joint_map = "<name>"`` in ``[motion]`` or
detected with ``"auto"`` (the first map whose required joints all exist in the clip; when none does,
``"auto"`` reads the map off the skeleton's names and hierarchy, :mod:`.name_match`, and calls it
``"matched"``):

- ``cmu``: the widely used CMU motion-capture BVH conversions (Hips, LHipJoint, LeftUpLeg,
  LeftLeg, LeftFoot, LeftToeBase, LowerBack, Spine, Spine1, Neck, Neck1, Head, LeftShoulder,
  LeftArm, LeftForeArm, LeftHand, ...); also every skeleton with these names;
- ``mixamo``: Adobe Mixamo exports, the same names with the ``mixamorig:`` prefix, plus
  ``mixamorig:HeadTop_End``;
- ``hip-knee``: LeftHip / LeftKnee / LeftAnkle / LeftToe legs and LeftShoulder / LeftElbow /
  LeftWrist arms (LeftCollar the clavicle);
- ``bandai``: ``_L``/``_R`` suffixes (UpperLeg_L, LowerLeg_L, Foot_L, Toes_L, UpperArm_L,
  LowerArm_L, Hand_L; Spine, Chest), as in the Bandai Namco Research motion datasets;
- ``cc-base``: Reallusion Character Creator / iClone exports (CC_Base_Hip, CC_Base_Waist,
  CC_Base_Spine01, CC_Base_Spine02, CC_Base_NeckTwist01, CC_Base_Head, CC_Base_L_Upperarm,
  CC_Base_L_Forearm, CC_Base_L_Hand, CC_Base_L_Thigh, CC_Base_L_Calf, CC_Base_L_Foot,
  CC_Base_L_ToeBase, ...; twist, share, finger and face bones ignored);
- ``daz``: the DAZ-friendly BVH conversions of the CMU database (hip, abdomen, chest, neck, head,
  lCollar, lShldr, lForeArm, lHand, lButtock, lThigh, lShin, lFoot; no toe joint);
- ``cmu-asf``: the CMU database's own ASF skeletons, read from ASF/AMC files (:mod:`.acclaim`):
  root, lhipjoint, lfemur, ltibia, lfoot, ltoes, lowerback, upperback, thorax, lowerneck,
  upperneck, head, lclavicle, lhumerus, lradius, lwrist, lhand, ... (the neck is ``lowerneck``,
  whose head is the thorax's end; the shoulder is ``lhumerus``, whose head is the clavicle's end);
- ``mocapnet``: the lower-case names of the MocapNET / MakeHuman skeletons (hip, abdomen, chest,
  neck, head, lcollar, lshoulder, lelbow, lhand, lhip, lknee, lfoot; the hip joint's parent is
  ``lbuttock`` or ``lhipjoint``; toes not mapped: their names differ between the variants);
- ``keypoints``: clips of joint keypoints (TRC marker files, :mod:`.keypoint_clips`), whose bones are named after
  silpose's roles (``pelvis``, ``neck``, ``l_shoulder`` ...).

Any other skeleton: a user TOML file, one ``role = "BVH joint name"`` line per role
(``joint_map = "my_map.toml"``, relative to the config file)::

    pelvis = "root"
    neck = "neck_base"
    head = "skull"
    l_shoulder = "arm_l"
    ...
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .name_match import match_joint_map

SIDES = ("l", "r")
LIMB_ROLES = ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")
#: Roles every clip must supply.
REQUIRED_ROLES: tuple[str, ...] = ("pelvis", "neck", "head") + tuple(f"{s}_{j}" for s in SIDES for j in LIMB_ROLES)
#: Roles a clip may supply.
OPTIONAL_ROLES: tuple[str, ...] = ("head_top", "l_toe", "r_toe")
ROLES: tuple[str, ...] = REQUIRED_ROLES + OPTIONAL_ROLES


def _sided(left: dict[str, str], right: dict[str, str]) -> dict[str, str]:
    return {**{f"l_{k}": v for k, v in left.items()}, **{f"r_{k}": v for k, v in right.items()}}


def _cmu_like(prefix: str = "") -> dict[str, str]:
    limbs = {"shoulder": "{}Arm", "elbow": "{}ForeArm", "wrist": "{}Hand", "hip": "{}UpLeg", "knee": "{}Leg",
             "ankle": "{}Foot", "toe": "{}ToeBase"}
    return {
        "pelvis": f"{prefix}Hips", "neck": f"{prefix}Neck", "head": f"{prefix}Head",
        **_sided({k: prefix + v.format("Left") for k, v in limbs.items()},
                 {k: prefix + v.format("Right") for k, v in limbs.items()}),
    }


#: Built-in maps, role -> BVH joint name (module docstring).
BUILTIN_MAPS: dict[str, dict[str, str]] = {
    "cmu": _cmu_like(),
    "mixamo": {**_cmu_like("mixamorig:"), "head_top": "mixamorig:HeadTop_End"},
    "hip-knee": {
        "pelvis": "Hips", "neck": "Neck", "head": "Head",
        **_sided({"shoulder": "LeftShoulder", "elbow": "LeftElbow", "wrist": "LeftWrist", "hip": "LeftHip",
                  "knee": "LeftKnee", "ankle": "LeftAnkle", "toe": "LeftToe"},
                 {"shoulder": "RightShoulder", "elbow": "RightElbow", "wrist": "RightWrist", "hip": "RightHip",
                  "knee": "RightKnee", "ankle": "RightAnkle", "toe": "RightToe"}),
    },
    "bandai": {
        "pelvis": "Hips", "neck": "Neck", "head": "Head",
        **_sided({"shoulder": "UpperArm_L", "elbow": "LowerArm_L", "wrist": "Hand_L", "hip": "UpperLeg_L",
                  "knee": "LowerLeg_L", "ankle": "Foot_L", "toe": "Toes_L"},
                 {"shoulder": "UpperArm_R", "elbow": "LowerArm_R", "wrist": "Hand_R", "hip": "UpperLeg_R",
                  "knee": "LowerLeg_R", "ankle": "Foot_R", "toe": "Toes_R"}),
    },
}
BUILTIN_MAPS["cc-base"] = {
    "pelvis": "CC_Base_Hip", "neck": "CC_Base_NeckTwist01", "head": "CC_Base_Head",
    **_sided({k: f"CC_Base_L_{v}" for k, v in (("shoulder", "Upperarm"), ("elbow", "Forearm"), ("wrist", "Hand"),
                                                ("hip", "Thigh"), ("knee", "Calf"), ("ankle", "Foot"), ("toe", "ToeBase"))},
             {k: f"CC_Base_R_{v}" for k, v in (("shoulder", "Upperarm"), ("elbow", "Forearm"), ("wrist", "Hand"),
                                                ("hip", "Thigh"), ("knee", "Calf"), ("ankle", "Foot"), ("toe", "ToeBase"))}),
}
BUILTIN_MAPS["daz"] = {
    "pelvis": "hip", "neck": "neck", "head": "head",
    **_sided({k: f"l{v}" for k, v in (("shoulder", "Shldr"), ("elbow", "ForeArm"), ("wrist", "Hand"), ("hip", "Thigh"),
                                       ("knee", "Shin"), ("ankle", "Foot"))},
             {k: f"r{v}" for k, v in (("shoulder", "Shldr"), ("elbow", "ForeArm"), ("wrist", "Hand"), ("hip", "Thigh"),
                                       ("knee", "Shin"), ("ankle", "Foot"))}),
}
BUILTIN_MAPS["mocapnet"] = {
    "pelvis": "hip", "neck": "neck", "head": "head",
    **_sided({k: f"l{v}" for k, v in (("shoulder", "shoulder"), ("elbow", "elbow"), ("wrist", "hand"), ("hip", "hip"),
                                       ("knee", "knee"), ("ankle", "foot"))},
             {k: f"r{v}" for k, v in (("shoulder", "shoulder"), ("elbow", "elbow"), ("wrist", "hand"), ("hip", "hip"),
                                       ("knee", "knee"), ("ankle", "foot"))}),
}
BUILTIN_MAPS["cmu-asf"] = {
    "pelvis": "root", "neck": "lowerneck", "head": "head",
    **_sided({k: f"l{v}" for k, v in (("shoulder", "humerus"), ("elbow", "radius"), ("wrist", "wrist"), ("hip", "femur"),
                                       ("knee", "tibia"), ("ankle", "foot"), ("toe", "toes"))},
             {k: f"r{v}" for k, v in (("shoulder", "humerus"), ("elbow", "radius"), ("wrist", "wrist"), ("hip", "femur"),
                                       ("knee", "tibia"), ("ankle", "foot"), ("toe", "toes"))}),
}
#: Keypoint clips (TRC, :mod:`.keypoint_clips`): one bone per role, named after the role.
BUILTIN_MAPS["keypoints"] = {r: r for r in ROLES}
#: Order in which ``"auto"`` tries the built-in maps.
AUTO_ORDER: tuple[str, ...] = ("cmu", "mixamo", "hip-knee", "bandai", "cc-base", "daz", "mocapnet", "cmu-asf",
                               "keypoints")
#: Name of the map ``"auto"`` reads off the skeleton when no built-in map fits (:mod:`.name_match`).
MATCHED_MAP = "matched"


class JointMapError(ValueError):
    """A joint map cannot be read or does not fit a clip; the message names the file and the field."""


def load_map_file(path: str | Path) -> dict[str, str]:
    """A user joint map TOML (``role = "BVH joint"`` lines); errors name the file and the field."""
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8-sig"))  # past a Windows editor's byte-order mark
    except FileNotFoundError:
        raise JointMapError(f"{path}: joint map file not found") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise JointMapError(f"{path}: not valid TOML ({exc})") from None
    unknown = sorted(set(raw) - set(ROLES))
    if unknown:
        raise JointMapError(f"{path}: field {unknown[0]!r}: unknown silpose joint; known: {', '.join(ROLES)}")
    for role, name in raw.items():
        if not isinstance(name, str) or not name:
            raise JointMapError(f"{path}: field {role!r} must be a BVH joint name (a non-empty string)")
    missing = [r for r in REQUIRED_ROLES if r not in raw]
    if missing:
        raise JointMapError(f"{path}: field {missing[0]!r} missing (required: {', '.join(REQUIRED_ROLES)})")
    return dict(raw)


def map_from_spec(spec: str, base: Path | None = None) -> dict[str, str] | None:
    """The role -> BVH name dict of ``spec`` (a built-in name or a TOML path), None for ``"auto"``."""
    if spec == "auto":
        return None
    if spec in BUILTIN_MAPS:
        return dict(BUILTIN_MAPS[spec])
    p = Path(spec).expanduser()
    if not p.is_absolute() and base is not None:
        p = base / p
    return load_map_file(p)


#: No turn: the clip's rest pose stands up the z axis.
UPRIGHT = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclass(frozen=True)
class ResolvedMap:
    """A joint map applied to one clip's skeleton (indices into the clip's BVH joints).

    Attributes:
        name: the map's name (built-in name or the TOML path).
        index: role -> BVH joint index, -1 for an optional role the clip lacks.
        spine_chain: BVH joint indices from the pelvis joint up to the neck joint (both included),
            the chain :mod:`.retarget` places silpose's spine joint on.
        head_tail: use the BVH head bone's tail as the head top (when ``head_top`` is not mapped).
        upright: 3x3 rotation (rows) applied to the clip's positions before anything else, so that its
            rest pose stands up +z (:func:`upright_turn`); identity for almost every file.
        rest_up: the axis (after Blender's Y-up import) the rest pose's spine pointed along: ``+z``,
            or e.g. ``-y`` for a file written Z up.
    """

    name: str
    index: dict[str, int]
    spine_chain: tuple[int, ...]
    head_tail: bool
    upright: tuple[tuple[float, float, float], ...] = UPRIGHT
    rest_up: str = "+z"


def upright_turn(spine: np.ndarray) -> tuple[tuple[tuple[float, float, float], ...], str]:
    """The quarter (or half) turn that stands a rest pose whose pelvis -> neck vector is ``spine`` (3,) up +z.

    A file's rest pose (its T- or A-pose) stands; one written with another up axis than its format
    says (a Z-up BVH, read as Y up, lies along -y) is turned by the smallest rotation taking the
    world axis nearest its spine to +z. Within 45 degrees of +z nothing is turned, so a clip whose
    rest pose leans is kept as it is. Returns the rotation (rows) and that axis (``"+z"``, ``"-y"``, ...).
    """
    s = np.asarray(spine, float)
    n = float(np.linalg.norm(s))
    if n < 1e-12 or s[2] / n >= np.cos(np.pi / 4):
        return UPRIGHT, "+z"
    k = int(np.argmax(np.abs(s)))
    sign = 1.0 if s[k] > 0 else -1.0
    name = ("+" if sign > 0 else "-") + "xyz"[k]
    a = np.zeros(3)
    a[k] = sign
    if k == 2:  # upside down: half a turn about x
        R = np.diag([1.0, -1.0, -1.0])
    else:  # a quarter turn about a x z, taking a to z
        axis = np.cross(a, [0.0, 0.0, 1.0])
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        R = np.eye(3) + K + K @ K  # Rodrigues' formula at 90 degrees (sin 1, 1 - cos 1)
    return tuple(tuple(float(v) for v in row) for row in np.round(R, 12)), name


def _path_to_ancestor(parents: list[int], child: int, ancestor: int) -> list[int] | None:
    chain = [child]
    while chain[-1] != ancestor:
        p = parents[chain[-1]]
        if p < 0:
            return None
        chain.append(p)
    return chain[::-1]


def _angle_ok(a, b, max_deg: float = 45.0) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na < 1e-9 or nb < 1e-9:
        return False
    return float(np.dot(a, b) / (na * nb)) >= float(np.cos(np.deg2rad(max_deg)))


def resolve_map(
    names: list[str], parents: list[int], rest_heads, rest_tails, spec: str, source: str, base: Path | None = None,
    find_up: bool = True,
) -> ResolvedMap:
    """Apply joint map ``spec`` (``"auto"``, a built-in name or a TOML path) to a clip's skeleton.

    Args:
        names, parents: the clip's BVH joints (Blender bones) and their parent indices (-1: root).
        rest_heads, rest_tails: (B, 3) rest-pose bone heads and tails (any unit).
        source: the clip file, for error messages.
        find_up: stand a clip whose rest pose lies (:func:`upright_turn`); False for files that state their
            axes (FBX, glTF), whose importers already turned them Z up.
    Raises:
        JointMapError (one line naming ``source``): a required joint is missing, no built-in map
        fits and the names leave a required role unmatched (``auto``), or the neck is not below the
        pelvis in the hierarchy.
    """
    where = {n: i for i, n in enumerate(names)}
    if spec == "auto":
        fits = [m for m in AUTO_ORDER if all(BUILTIN_MAPS[m][r] in where for r in REQUIRED_ROLES)]
        matched = {} if fits else match_joint_map(names, parents)
        unmatched = [r for r in REQUIRED_ROLES if r not in matched]
        if not fits and unmatched:
            raise JointMapError(
                f"{source}: joint names match no built-in map ({', '.join(AUTO_ORDER)}) and no joint reads as "
                f"silpose {', '.join(unmatched[:4])}{' ...' if len(unmatched) > 4 else ''}; give [motion] "
                f"joint_map = \"map.toml\" (clip joints: {', '.join(names[:6])}{' ...' if len(names) > 6 else ''})"
            )
        name, table = (fits[0], BUILTIN_MAPS[fits[0]]) if fits else (MATCHED_MAP, matched)
    else:
        table = map_from_spec(spec, base)
        name = spec
    missing = [r for r in REQUIRED_ROLES if table.get(r) not in where]
    if missing:
        raise JointMapError(
            f"{source}: joint map {name!r}: BVH joint {table.get(missing[0])!r} (silpose {missing[0]}) not in the clip "
            f"(clip joints: {', '.join(names[:6])}{' ...' if len(names) > 6 else ''})"
        )
    index = {r: where.get(table[r], -1) if r in table else -1 for r in ROLES}
    chain = _path_to_ancestor(parents, index["neck"], index["pelvis"])
    if chain is None:
        raise JointMapError(f"{source}: joint map {name!r}: neck joint {table['neck']!r} is not below the pelvis "
                            f"joint {table['pelvis']!r} in the hierarchy")
    h, n = index["head"], index["neck"]
    heads, tails = np.asarray(rest_heads, float), np.asarray(rest_tails, float)
    head_tail = index["head_top"] < 0 and _angle_ok(tails[h] - heads[h], heads[h] - heads[n])
    upright, rest_up = upright_turn(heads[n] - heads[index["pelvis"]]) if find_up else (UPRIGHT, "+z")
    return ResolvedMap(name=name, index=index, spine_chain=tuple(chain), head_tail=bool(head_tail), upright=upright,
                       rest_up=rest_up)
