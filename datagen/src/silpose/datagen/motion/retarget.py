"""Retargeting one motion-capture frame onto a subject's 19-joint skeleton (pure numpy).

Input: the world positions of the clip's BVH joints in one frame (Blender's import, z up), the
joint map applied to the clip (:class:`joint_maps.ResolvedMap`) and a subject. Output: the
global rotation of every silpose bone and the posed joints in the body frame
(docs/conventions.md, "Skeleton"; :mod:`.walk` for the frames and forward kinematics).

What comes from the clip and what from the subject:

- **Bone directions** come from the clip: every silpose bone whose two ends are mapped joints
  points from the clip's parent joint to its child joint (thigh hip -> knee, shank knee -> ankle,
  foot ankle -> toe, upper arm shoulder -> elbow, forearm elbow -> wrist, head neck -> head).
- **Pelvis and chest orientation** come from the clip: the pelvis frame has its y axis along the
  clip's right-hip -> left-hip line and its z axis along the lower torso (pelvis -> spine point,
  orthogonalised); the chest frame likewise from the shoulder joints and the upper torso
  (spine point -> neck). silpose's hip bones (pelvis -> hip) and shoulder bones (neck ->
  shoulder) turn with these frames, so they point along the clip's hip and shoulder lines.
- **Spine**: silpose's spine joint is the point of the clip's spine chain (pelvis, every BVH
  joint up to the neck, neck: a polyline) at the subject's fraction of the torso,
  ``torso_lower / (torso_lower + torso_upper)`` of the chain's length; extra spine joints are
  thereby collapsed.
- **Bone lengths** are the subject's own (:func:`walk.rest_skeleton`): a joint is its parent plus
  the subject's segment length along the clip's direction, ``p_c = p_parent + L_c d_c``.
- **Missing joints**: without a toe joint the foot keeps the subject's rest orientation relative to
  the shank; without a head top (:mod:`.joint_maps`) the head-top bone continues the neck-to-head
  direction. Extra BVH joints are ignored.
- **Placement**: the clip's own root trajectory is dropped: the pose is expressed in a body frame
  with the pelvis above the origin and x along the clip pelvis's forward direction (horizontal,
  perpendicular to the hip line), so heading and floor position are the sample's own draws; the
  feet are put back on the floor (the lowest heel or toe at z = 0, :func:`walk.foot_points`)
  by :class:`bvh_motion.BvhMotion`.
- **Mirror**: a mirrored frame reflects the clip through a vertical plane and swaps left and
  right (augmentation).

Twist about a bone's own axis is not in the clip's joint positions; each bone takes the smallest
rotation (swing) from its parent's frame, which leaves the joints exact.
"""

from __future__ import annotations

import numpy as np

from silpose.shared.skeleton import JOINT_NAMES, N_JOINTS, PARENTS

from .joint_maps import ResolvedMap
from ..subjects import segment_lengths
from ..walk import euler_matrix, rest_skeleton

#: Directions shorter than this (in the clip's unit) count as undefined.
EPS = 1e-9

#: silpose bone (child joint) -> (BVH role of the parent end, BVH role of the child end), for the
#: bones whose direction is the clip's joint-to-joint direction.
DIRECTION_BONES: dict[str, tuple[str, str]] = {
    "head": ("neck", "head"),
    **{f"{s}_elbow": (f"{s}_shoulder", f"{s}_elbow") for s in "lr"},
    **{f"{s}_wrist": (f"{s}_elbow", f"{s}_wrist") for s in "lr"},
    **{f"{s}_knee": (f"{s}_hip", f"{s}_knee") for s in "lr"},
    **{f"{s}_ankle": (f"{s}_knee", f"{s}_ankle") for s in "lr"},
    **{f"{s}_toe": (f"{s}_ankle", f"{s}_toe") for s in "lr"},
}

_MIRROR = np.diag([-1.0, 1.0, 1.0])


def _unit(v: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(v))
    return None if n < EPS else v / n


def swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) smallest rotation taking unit vector ``a`` to unit vector ``b`` (Rodrigues)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:  # opposite: half a turn about any axis perpendicular to a
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def frame_from(lateral: np.ndarray, up: np.ndarray) -> np.ndarray | None:
    """(3, 3) body-axes frame, columns (forward, left, up): y along ``lateral``, z along ``up``
    made perpendicular to it, x = y x z; None if degenerate."""
    y = _unit(lateral)
    if y is None:
        return None
    z = _unit(up - np.dot(up, y) * y)
    if z is None:
        return None
    return np.stack([np.cross(y, z), y, z], axis=1)


def polyline_point(points: np.ndarray, fraction: float) -> np.ndarray:
    """The point at ``fraction`` of the arc length of the polyline ``points`` (k, 3)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    total = float(seg.sum())
    if total < EPS:
        return points[0].copy()
    target = fraction * total
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    i = int(np.clip(np.searchsorted(cum, target, side="right") - 1, 0, len(seg) - 1))
    t = (target - cum[i]) / seg[i] if seg[i] > EPS else 0.0
    return points[i] + t * (points[i + 1] - points[i])


def heading_of(lateral: np.ndarray) -> float:
    """Yaw (radians, counter-clockwise from +x) of the forward direction perpendicular to the
    horizontal part of ``lateral`` (a body's right-to-left line): forward = lateral turned -90°."""
    return float(np.arctan2(lateral[1], lateral[0]) - np.pi / 2)


def clip_points(heads: np.ndarray, tails: np.ndarray, jmap: ResolvedMap, mirror: bool) -> dict[str, np.ndarray]:
    """The clip frame's role positions (plus ``chain`` (k, 3) and ``head_end``), mirrored if asked.

    Args:
        heads, tails: (B, 3) world positions of the clip's bone heads and tails in one frame.
    """
    idx = dict(jmap.index)
    if jmap.rest_up != "+z":  # a file written with another up axis (joint_maps.upright_turn)
        U = np.asarray(jmap.upright)
        heads, tails = heads @ U.T, tails @ U.T
    if mirror:
        heads, tails = heads @ _MIRROR.T, tails @ _MIRROR.T
        idx = {(("r" + r[1:]) if r.startswith("l_") else ("l" + r[1:]) if r.startswith("r_") else r): i
               for r, i in idx.items()}
    pts = {r: heads[i] for r, i in idx.items() if i >= 0}
    pts["chain"] = heads[list(jmap.spine_chain)]
    if "head_top" not in pts and jmap.head_tail:
        pts["head_top"] = tails[idx["head"]]
    return pts


#: The roles a leg swap takes from the second frame (:func:`combine_legs`).
LEG_ROLES: tuple[str, ...] = tuple(f"{s}_{j}" for s in "lr" for j in ("hip", "knee", "ankle", "toe"))


def combine_legs(upper: dict[str, np.ndarray], lower: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Role positions (:func:`clip_points`) with the hips and legs of ``lower`` and everything else
    of ``upper`` (part-mixing augmentation, ``[motion] part_mix``).

    ``lower``'s leg roles (:data:`LEG_ROLES`) are taken relative to its pelvis, turned about the
    vertical by the difference of the two frames' hip-line headings (:func:`heading_of`) and put at
    ``upper``'s pelvis: ``p = pelvis_u + Rz(yaw_u - yaw_l) (p_l - pelvis_l)``. So the legs keep
    their own shape and tilt, and face where the upper body's hips faced; ``upper``'s leg roles
    (its toes too, when ``lower`` has none) are dropped.
    """
    yaw_u = heading_of(upper["l_hip"] - upper["r_hip"])
    yaw_l = heading_of(lower["l_hip"] - lower["r_hip"])
    turn = euler_matrix((0.0, 0.0, yaw_u - yaw_l))
    out = {k: v for k, v in upper.items() if k not in LEG_ROLES}
    for role in LEG_ROLES:
        if role in lower:
            out[role] = upper["pelvis"] + turn @ (lower[role] - lower["pelvis"])
    return out


#: The limbs :func:`swing_limbs` turns: name -> (pivot role, roles turned with it).
LIMBS: dict[str, tuple[str, tuple[str, ...]]] = {
    **{f"{s}_arm": (f"{s}_shoulder", (f"{s}_elbow", f"{s}_wrist")) for s in "lr"},
    **{f"{s}_leg": (f"{s}_hip", (f"{s}_knee", f"{s}_ankle", f"{s}_toe")) for s in "lr"},
}


def rotation_from_vector(v: np.ndarray) -> np.ndarray:
    """(3, 3) rotation by ``|v|`` radians about ``v / |v|`` (Rodrigues' formula,
    ``R = I + sin t K + (1 - cos t) K^2`` with ``K`` the cross-product matrix of the unit axis)."""
    v = np.asarray(v, np.float64)
    t = float(np.linalg.norm(v))
    if t < EPS:
        return np.eye(3)
    k = v / t
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(t) * K + (1.0 - np.cos(t)) * (K @ K)


def swing_limbs(pts: dict[str, np.ndarray], swings: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Role positions (:func:`clip_points`) with each limb of ``swings`` (:data:`LIMBS` name -> (3,) rotation
    vector, radians, world axes) turned about its pivot as a rigid chain: ``p = pivot + R (p - pivot)``
    (:func:`rotation_from_vector`), so bone lengths and the elbow and knee angles are kept (limb-swing
    augmentation, ``[motion] limb_swing``). Roles a clip lacks are skipped."""
    out = dict(pts)
    for limb, v in swings.items():
        pivot, roles = LIMBS[limb]
        if pivot not in pts:
            continue
        R = rotation_from_vector(v)
        for r in roles:
            if r in pts:
                out[r] = pts[pivot] + R @ (pts[r] - pts[pivot])
    return out


#: The roles a pose stands on (the floor touches the lowest of them).
FOOT_ROLES: tuple[str, ...] = ("l_ankle", "r_ankle", "l_toe", "r_toe")


def above_feet(pts: dict[str, np.ndarray], margin: float = 0.02) -> bool:
    """Whether no role of ``pts`` (:func:`clip_points`, metres, z up) but the feet is more than
    ``margin`` metres below the lowest foot role: a pose that can stand with its feet on the floor."""
    feet = min(float(pts[r][2]) for r in FOOT_ROLES if r in pts)
    rest = min(float(v[2]) for k, v in pts.items() if k not in FOOT_ROLES and np.ndim(v) == 1)
    return rest >= feet - margin


def retarget_frame(pts: dict[str, np.ndarray], subject: dict[str, float]) -> tuple[np.ndarray, np.ndarray, float]:
    """Retarget one clip frame (:func:`clip_points`) onto ``subject`` (module docstring).

    Returns:
        joints: (19, 3) posed joints in the body frame (pelvis at its rest height above the origin).
        rotations: (19, 3, 3) global rotation of each bone (index = child joint; row 0 = I), about
            the rest body axes: ``joints[c] = joints[parent] + rotations[c] (rest[c] - rest[parent])``.
        yaw: the clip pelvis's heading that was removed (radians).
    """
    L = segment_lengths(subject)
    rest = rest_skeleton(subject)
    pelvis = pts["pelvis"]
    lateral = pts["l_hip"] - pts["r_hip"]
    if np.hypot(lateral[0], lateral[1]) < EPS:
        lateral = pts["l_shoulder"] - pts["r_shoulder"]
    yaw = heading_of(lateral)
    H = euler_matrix((0.0, 0.0, yaw))
    q = {k: (v - pelvis) @ H for k, v in pts.items()}  # body frame: H^T (p - pelvis)
    spine_pt = polyline_point(q["chain"], L["torso_lower"] / (L["torso_lower"] + L["torso_upper"]))

    G = np.zeros((N_JOINTS, 3, 3))
    G[0] = np.eye(3)
    F_pelvis = frame_from(q["l_hip"] - q["r_hip"], spine_pt)
    F_chest = frame_from(q["l_shoulder"] - q["r_shoulder"], q["neck"] - spine_pt)
    targets = {"spine": spine_pt, "neck": q["neck"] - spine_pt}
    for bone, (a, b) in DIRECTION_BONES.items():
        if a in q and b in q:
            targets[bone] = q[b] - q[a]
    targets["head_top"] = q["head_top"] - q["head"] if "head_top" in q else q["head"] - q["neck"]
    for c in range(1, N_JOINTS):
        name, p = JOINT_NAMES[c], PARENTS[c]
        if name in ("l_hip", "r_hip") and F_pelvis is not None:
            G[c] = F_pelvis
            continue
        if name in ("l_shoulder", "r_shoulder") and F_chest is not None:
            G[c] = F_chest
            continue
        r = _unit(rest[c] - rest[p])
        here = G[p] @ r
        d = _unit(targets[name]) if name in targets else None
        G[c] = G[p] if d is None else swing(here, d) @ G[p]
    J = np.zeros_like(rest)
    J[0] = rest[0]
    for c in range(1, N_JOINTS):
        J[c] = J[PARENTS[c]] + G[c] @ (rest[c] - rest[PARENTS[c]])
    return J, G, yaw


def local_rotations(G: np.ndarray) -> dict[str, np.ndarray]:
    """``{bone: (3, 3)}`` local rotations ``R_c = G_parent^T G_c`` of global rotations ``G`` (19, 3, 3)."""
    return {JOINT_NAMES[c]: G[PARENTS[c]].T @ G[c] for c in range(1, N_JOINTS)}

