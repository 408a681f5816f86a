"""A procedural walk cycle and forward kinematics of the 19-joint skeleton. Pure numpy.

Frames. The *body frame* has x forward, y to the subject's left, z up, metres. The rest pose
stands straight with the arms hanging; the world pose is the body rotated by ``heading`` about
z (``heading`` = walking direction, radians counter-clockwise from world +x) and translated to
``(x, y, z0)``, where ``z0`` puts the lowest heel or toe on the floor (z = 0).

Bones. One bone per non-root joint, named after its *child* joint (``"l_knee"`` is the thigh,
hip -> knee). A bone rotates the subtree below it about its head (the parent joint). Rotations
are Euler angles ``(roll, pitch, yaw)`` about the body axes (x, y, z) of the REST pose,
``R = Rz(yaw) Ry(pitch) Rx(roll)``, composed down the chain: ``G_c = G_parent(c) R_c`` and
``p_c = p_parent + G_c (rest_c - rest_parent)`` (standard forward kinematics).
With these axes a leg or arm segment hanging down swings forward for NEGATIVE pitch and the
knee bends (shank backward) for positive pitch.

Walk cycle. Phase ``phase`` in [0, 1) starts at the left heel strike; stance is the first 60 %
of the cycle, swing the last 40 % (Perry & Burnfield, *Gait Analysis*; Winter's normative
sagittal angles). Each sagittal angle is the mean plus two (knee, ankle: three) Fourier harmonics,
``a(p) = a0 + sum_{k=1..K} (b_k cos 2 pi k p + c_k sin 2 pi k p)`` (Troje's eigenwalker
form), fitted by least squares to the normative knots in :data:`NORMATIVE_KNOTS` once at
import. The right leg runs half a cycle after the left; each arm swings with the opposite leg.
Per-subject style scales the amplitudes about the mean (``stride`` for hip and ankle,
``knee_flex`` for the knee, ``arm_swing`` for shoulder and elbow).
"""

from __future__ import annotations

import math

import numpy as np

from silpose.shared.rig_frame import DEFAULT_WORKSPACE, Workspace
from silpose.shared.skeleton import JOINT_INDEX, JOINT_NAMES, N_JOINTS, PARENTS

from .subjects import segment_lengths

#: Gait parameter keys, in record order. Angles in radians, positions in metres.
GAIT_FIELDS: tuple[str, ...] = (
    "phase",  # [0, 1), 0 = left heel strike
    "stride",  # amplitude multiplier for hip and ankle
    "arm_swing",  # amplitude multiplier for shoulder and elbow
    "knee_flex",  # amplitude multiplier for the knee
    "arm_abduction",  # radians, arms held out from the body
    "torso_lean",  # radians, forward lean of the trunk
    "pelvis_rotation",  # radians, amplitude of the transverse pelvis rotation
    "heading",  # radians, walking direction (counter-clockwise from world +x)
    "x",  # metres, pelvis position on the floor
    "y",
)

GAIT_RANGES: dict[str, tuple[float, float]] = {
    "phase": (0.0, 1.0),
    "stride": (0.8, 1.2),
    "arm_swing": (0.6, 1.4),
    "knee_flex": (0.85, 1.15),
    "arm_abduction": (np.deg2rad(6.0), np.deg2rad(14.0)),
    "torso_lean": (np.deg2rad(0.0), np.deg2rad(6.0)),
    "pelvis_rotation": (np.deg2rad(2.0), np.deg2rad(6.0)),
    "heading": (0.0, 2 * np.pi),
    "x": DEFAULT_WORKSPACE.bounds[0],  # the pelvis position: uniform on the rig's workspace
    "y": DEFAULT_WORKSPACE.bounds[1],  # (these two: the built-in 3 m x 3 m square; see gait_ranges)
}


def gait_ranges(workspace: Workspace = DEFAULT_WORKSPACE) -> dict[str, tuple[float, float]]:
    """:data:`GAIT_RANGES` with the pelvis position ``x``, ``y`` ranging over ``workspace``'s bounds."""
    (x0, x1), (y0, y1) = workspace.bounds
    return {**GAIT_RANGES, "x": (x0, x1), "y": (y0, y1)}


STANCE_FRACTION = 0.6
#: Anterior pelvic tilt (radians). Hip angles are measured against the pelvis, which tilts
#: forward ~8-10 deg while walking (Perry & Burnfield), so the thigh's absolute angle is the hip
#: angle minus the tilt: +17 deg at heel strike to -18 deg at 50 % (Winter's thigh angles).
PELVIC_TILT = float(np.deg2rad(8.0))

#: Normative sagittal angles (percent of cycle, degrees) for the LEFT limb, phase 0 = left heel
#: strike. Hip/shoulder/elbow: flexion positive; knee: flexion positive; ankle: dorsiflexion
#: positive. Shoulder and elbow follow the opposite (right) leg: peak flexion near 50 %.
NORMATIVE_KNOTS: dict[str, np.ndarray] = {
    "hip": np.array([[0, 25], [10, 22], [30, 8], [50, -10], [60, -5], [75, 15], [87, 27], [95, 26]], float),
    "knee": np.array(
        [[0, 5], [12, 18], [25, 12], [40, 5], [50, 22], [60, 40], [72, 66], [85, 40], [95, 8]], float
    ),
    "ankle": np.array(
        [[0, 0], [8, -6], [30, 8], [45, 10], [55, 0], [62, -22], [67, -20], [75, -8], [87, 1], [95, 0]], float
    ),
    "shoulder": np.array([[0, -15], [25, 0], [50, 15], [75, 0]], float),
    "elbow": np.array([[0, 12], [25, 22], [50, 35], [75, 22]], float),
}
#: Harmonics per angle. Two reproduce hip, shoulder and elbow; the knee's loading-response
#: bump (~18 deg at 12 %) and the ankle's toe-off plantarflexion (~20 deg) need a third.
N_HARMONICS = {"hip": 2, "knee": 3, "ankle": 3, "shoulder": 2, "elbow": 2}


def _design(phase: np.ndarray, n_harm: int) -> np.ndarray:
    """(P, 1 + 2 n_harm) Fourier design matrix [1, cos 2pi k p, sin 2pi k p]."""
    phase = np.asarray(phase, dtype=np.float64).reshape(-1)
    cols = [np.ones_like(phase)]
    for k in range(1, n_harm + 1):
        cols += [np.cos(2 * np.pi * k * phase), np.sin(2 * np.pi * k * phase)]
    return np.stack(cols, axis=1)


def _fit(knots: np.ndarray, n_harm: int) -> np.ndarray:
    """Least-squares Fourier coefficients (1 + 2 n_harm,) in degrees for (P, 2) knots."""
    A = _design(knots[:, 0] / 100.0, n_harm)
    coef, *_ = np.linalg.lstsq(A, knots[:, 1], rcond=None)
    return coef


#: Fitted coefficients (degrees) per angle: [a0, b1, c1, b2, c2, ...].
FOURIER_COEFFS: dict[str, np.ndarray] = {k: _fit(v, N_HARMONICS[k]) for k, v in NORMATIVE_KNOTS.items()}


def sagittal_angle(name: str, phase, amplitude: float = 1.0) -> np.ndarray:
    """Walk-cycle angle ``name`` (a key of :data:`FOURIER_COEFFS`) at ``phase``, radians.

    ``amplitude`` scales the harmonics about the mean a0. ``phase`` may be an array; the
    result has its shape (a 0-d array for a scalar phase).
    """
    phase = np.asarray(phase, dtype=np.float64)
    coef = FOURIER_COEFFS[name]
    k = np.arange(1, N_HARMONICS[name] + 1)
    arg = 2 * np.pi * phase[..., None] * k
    val = coef[0] + amplitude * (np.cos(arg) @ coef[1::2] + np.sin(arg) @ coef[2::2])
    return np.deg2rad(val)


def sample_gait(rng: np.random.Generator, workspace: Workspace = DEFAULT_WORKSPACE) -> dict[str, float]:
    """Draw gait parameters (keys :data:`GAIT_FIELDS` in order, uniform on :func:`gait_ranges`, the
    position anywhere in ``workspace``)."""
    ranges = gait_ranges(workspace)
    return {k: float(rng.uniform(*ranges[k])) for k in GAIT_FIELDS}


def _euler(roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> np.ndarray:
    return np.array([roll, pitch, yaw], dtype=np.float64)


def joint_angles(gait: dict[str, float]) -> dict[str, np.ndarray]:
    """Bone rotations for a gait: ``{bone: (3,) (roll, pitch, yaw) radians}`` (module docstring).

    Bones are named after their child joint (``JOINT_NAMES[1:]``); bones not listed in the
    walk (neck, head, head top) get zeros.
    """
    p = float(gait["phase"]) % 1.0
    stride, arm, knee = float(gait["stride"]), float(gait["arm_swing"]), float(gait["knee_flex"])
    out = {name: np.zeros(3) for name in JOINT_NAMES[1:]}
    pelvis_yaw = -float(gait["pelvis_rotation"]) * np.cos(2 * np.pi * p)  # left hip forward at p=0
    out["l_hip"] = _euler(pitch=PELVIC_TILT, yaw=pelvis_yaw)
    out["r_hip"] = _euler(pitch=PELVIC_TILT, yaw=pelvis_yaw)
    # trunk counter-rotates against the pelvis (relative to the rest frame) and leans forward
    out["spine"] = _euler(pitch=float(gait["torso_lean"]), yaw=-0.6 * pelvis_yaw)
    out["neck"] = _euler(pitch=-0.5 * float(gait["torso_lean"]))  # keep the gaze level
    for side, sgn, leg_phase in (("l", 1.0, p), ("r", -1.0, (p + 0.5) % 1.0)):
        arm_phase = leg_phase  # knots for the arm already follow the opposite leg
        out[f"{side}_knee"] = _euler(pitch=-float(sagittal_angle("hip", leg_phase, stride)))
        out[f"{side}_ankle"] = _euler(pitch=float(sagittal_angle("knee", leg_phase, knee)))
        out[f"{side}_toe"] = _euler(pitch=-float(sagittal_angle("ankle", leg_phase, stride)))
        out[f"{side}_elbow"] = _euler(
            roll=sgn * float(gait["arm_abduction"]), pitch=-float(sagittal_angle("shoulder", arm_phase, arm))
        )
        out[f"{side}_wrist"] = _euler(pitch=-float(sagittal_angle("elbow", arm_phase, arm)))
    return out


def rest_skeleton(subject: dict[str, float]) -> np.ndarray:
    """(19, 3) rest-pose joint positions in the body frame, metres (feet on the floor)."""
    L = segment_lengths(subject)
    J = np.zeros((N_JOINTS, 3))
    ix = JOINT_INDEX

    def put(name, parent, offset):
        J[ix[name]] = J[ix[parent]] + np.asarray(offset, float)

    J[ix["pelvis"]] = (0.0, 0.0, L["ankle"] + L["shank"] + L["thigh"])
    put("spine", "pelvis", (0, 0, L["torso_lower"]))
    put("neck", "spine", (0, 0, L["torso_upper"]))
    put("head", "neck", (0, 0, L["neck"]))
    put("head_top", "head", (0, 0, L["head"]))
    for side, sgn in (("l", 1.0), ("r", -1.0)):
        put(f"{side}_shoulder", "neck", (0, sgn * L["shoulder_width"] / 2, 0))
        put(f"{side}_elbow", f"{side}_shoulder", (0, 0, -L["upper_arm"]))
        put(f"{side}_wrist", f"{side}_elbow", (0, 0, -L["forearm"]))
        put(f"{side}_hip", "pelvis", (0, sgn * L["hip_width"] / 2, 0))
        put(f"{side}_knee", f"{side}_hip", (0, 0, -L["thigh"]))
        put(f"{side}_ankle", f"{side}_knee", (0, 0, -L["shank"]))
        put(f"{side}_toe", f"{side}_ankle", (0.75 * L["foot"], 0, -L["ankle"]))
    return J


def euler_matrix(angles) -> np.ndarray:
    """(3, 3) rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` for ``angles`` = (roll, pitch, yaw) radians."""
    a, b, c = (float(v) for v in angles)
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    # closed form of Rz @ Ry @ Rx
    return np.array(
        [
            [cc * cb, cc * sb * sa - sc * ca, cc * sb * ca + sc * sa],
            [sc * cb, sc * sb * sa + cc * ca, sc * sb * ca - cc * sa],
            [-sb, cb * sa, cb * ca],
        ]
    )


def posed_body(subject: dict[str, float], gait: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics in the body frame.

    Returns:
        joints: (19, 3) posed joint positions in the body frame (pelvis at its rest height).
        rotations: (19, 3, 3) global rotation of each bone (index = child joint; row 0 = I).
    """
    rest = rest_skeleton(subject)
    angles = joint_angles(gait)
    G = np.zeros((N_JOINTS, 3, 3))
    G[0] = np.eye(3)
    J = np.zeros_like(rest)
    J[0] = rest[0]
    for c in range(1, N_JOINTS):  # parents precede children in JOINT_NAMES
        p = PARENTS[c]
        G[c] = G[p] @ euler_matrix(angles[JOINT_NAMES[c]])
        J[c] = J[p] + G[c] @ (rest[c] - rest[p])
    return J, G


def foot_points(subject: dict[str, float], joints: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """(4, 3) heel and toe points of both feet (l_heel, l_toe, r_heel, r_toe), body frame.

    The heel sits a quarter foot length behind and ``ankle height`` below the ankle and turns
    with the foot bone; the toe is the toe joint.
    """
    L = segment_lengths(subject)
    heel = np.array([-0.25 * L["foot"], 0.0, -L["ankle"]])
    out = []
    for side in ("l", "r"):
        toe = JOINT_INDEX[f"{side}_toe"]
        out += [joints[JOINT_INDEX[f"{side}_ankle"]] + rotations[toe] @ heel, joints[toe]]
    return np.array(out)


def root_transform(subject: dict[str, float], gait: dict[str, float], posed: tuple | None = None) -> np.ndarray:
    """(4, 4) body -> world transform: heading about z, then translation to (x, y, z0).

    ``z0`` lifts or lowers the body so the lowest heel or toe (:func:`foot_points`) touches the
    floor. ``posed`` is :func:`posed_body`'s result if already computed.
    """
    J, G = posed_body(subject, gait) if posed is None else posed
    z0 = -float(foot_points(subject, J, G)[:, 2].min())
    h = float(gait["heading"])
    T = np.eye(4)
    T[:3, :3] = euler_matrix((0.0, 0.0, h))
    T[:3, 3] = (float(gait["x"]), float(gait["y"]), z0)
    return T


def skeleton_positions(subject: dict[str, float], gait: dict[str, float]) -> np.ndarray:
    """(19, 3) posed joint positions in world metres, ``JOINT_NAMES`` order."""
    J, G = posed_body(subject, gait)
    T = root_transform(subject, gait, (J, G))
    return J @ T[:3, :3].T + T[:3, 3]


def describe_distribution(workspace: Workspace = DEFAULT_WORKSPACE) -> dict:
    """The gait distribution of :func:`sample_gait` on ``workspace`` and the walk model, as plain data
    (dataset card)."""
    units = {
        "phase": "cycle fraction (0 = left heel strike)",
        "stride": "amplitude multiplier (hip, ankle)",
        "arm_swing": "amplitude multiplier (shoulder, elbow)",
        "knee_flex": "amplitude multiplier (knee)",
        "arm_abduction": "radians",
        "torso_lean": "radians",
        "pelvis_rotation": "radians",
        "heading": "radians, counter-clockwise from world +x",
        "x": "metres",
        "y": "metres",
    }
    return {
        "fields": {
            k: {"distribution": "uniform", "low": float(lo), "high": float(hi), "unit": units[k]}
            for k, (lo, hi) in gait_ranges(workspace).items()
        },
        "walk_model": {
            "form": "mean + K Fourier harmonics per sagittal angle, least-squares fit to normative knots",
            "harmonics": dict(N_HARMONICS),
            "knots_percent_degrees": {k: v.tolist() for k, v in NORMATIVE_KNOTS.items()},
            "stance_fraction": STANCE_FRACTION,
            "pelvic_tilt_deg": float(np.rad2deg(PELVIC_TILT)),
            "right_leg": "half a cycle after the left; each arm swings with the opposite leg",
        },
    }
