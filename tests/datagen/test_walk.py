"""Walk cycle: normative angle ranges, stance/swing timing, symmetry, sampling, kinematics."""

import numpy as np
import pytest

from silpose.datagen import walk
from silpose.datagen.subjects import sample_subject
from silpose.shared.skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS

P = np.linspace(0.0, 1.0, 1001)[:-1]


def deg(name, amplitude=1.0):
    return np.rad2deg(walk.sagittal_angle(name, P, amplitude))


def test_hip_range_and_timing():
    h = deg("hip")
    assert 20 <= h[0] <= 30  # flexion at heel strike
    assert -13 <= h.min() <= -7 and 0.4 <= P[h.argmin()] <= 0.6  # ~10 deg extension near 50 %
    assert 20 <= h.max() <= 32 and P[h.argmax()] >= 0.8  # max flexion late in swing


def test_knee_range_and_timing():
    k = deg("knee")
    loading = k[(P > 0.05) & (P < 0.25)].max()
    assert 15 <= loading <= 22  # loading response
    assert 33 <= np.interp(0.60, P, k) <= 47  # toe-off at the end of stance (60 %)
    assert 60 <= k.max() <= 70 and 0.65 <= P[k.argmax()] <= 0.8  # mid-swing peak
    assert k.min() > -2  # never hyper-extended


def test_ankle_plantarflexion_at_toe_off():
    a = deg("ankle")
    assert -24 <= a.min() <= -16 and 0.58 <= P[a.argmin()] <= 0.72
    assert 5 <= a[(P > 0.2) & (P < 0.5)].max() <= 16  # dorsiflexion late in stance


def test_arm_arc_and_elbow():
    s = deg("shoulder")
    assert 25 <= s.max() - s.min() <= 35  # ~30 deg arc
    e = deg("elbow")
    assert e.min() > 5 and e.max() < 45
    assert abs(P[e.argmax()] - P[s.argmax()]) < 0.05  # elbow bends with the forward swing


def test_style_scales_amplitude_about_mean():
    h1, h2 = deg("hip"), deg("hip", 1.2)
    c = walk.FOURIER_COEFFS["hip"][0]
    np.testing.assert_allclose(h2 - c, 1.2 * (h1 - c), atol=1e-9)
    assert walk.N_HARMONICS["hip"] <= 2 and max(walk.N_HARMONICS.values()) <= 3


def test_stance_swing_from_foot_contact_and_right_leg_half_cycle_later():
    rng = np.random.default_rng(0)
    s = sample_subject(rng, "train")
    g = dict(walk.sample_gait(rng), heading=0.0, x=0.0, y=0.0, stride=1.0, knee_flex=1.0)
    phases = P[::10]
    low_l, low_r, left_ang, right_ang = [], [], [], []
    for p in phases:
        gp = dict(g, phase=float(p))
        J, G = walk.posed_body(s, gp)
        feet = walk.foot_points(s, J, G)[:, 2] + walk.root_transform(s, gp)[2, 3]
        low_l.append(feet[:2].min())
        low_r.append(feet[2:].min())
        a = walk.joint_angles(gp)
        left_ang.append(a["l_knee"][1])
        right_ang.append(a["r_knee"][1])
    low_l, low_r = np.array(low_l), np.array(low_r)
    # the body always stands on the floor
    np.testing.assert_allclose(np.minimum(low_l, low_r), 0.0, atol=1e-9)
    # stance (first 60 %): the left foot stays on (within 3 cm of) the floor until toe-off
    assert np.all(low_l[phases < 0.55] < 0.03)
    # swing (60-100 %): the foot is lifted clearly during early and mid swing
    assert np.all(low_l[(phases > 0.6) & (phases < 0.76)] > 0.03)
    # the toe-off knee angle rises fast (~40 deg at 60 %) and the ankle is plantarflexed there
    assert np.rad2deg(walk.sagittal_angle("knee", 0.6)) > 30
    assert np.rad2deg(walk.sagittal_angle("ankle", 0.62)) < -12
    # right leg is the left one shifted by half a cycle
    n = len(left_ang)
    np.testing.assert_allclose(np.roll(left_ang, -n // 2), right_ang, atol=1e-12)
    np.testing.assert_allclose(np.roll(low_l, -n // 2), low_r, atol=1e-9)


def test_arms_opposite_to_legs():
    g = dict(walk.sample_gait(np.random.default_rng(1)), phase=0.0)  # left heel strike: left leg forward
    a = walk.joint_angles(g)
    assert a["l_knee"][1] < 0  # left hip flexed (negative pitch swings forward)
    assert a["l_elbow"][1] > 0 and a["r_elbow"][1] < 0  # left arm back, right arm forward


def test_gait_sampling_deterministic_and_in_range():
    a = walk.sample_gait(np.random.default_rng(5))
    assert a == walk.sample_gait(np.random.default_rng(5))
    assert tuple(a) == walk.GAIT_FIELDS
    rng = np.random.default_rng(6)
    draws = [walk.sample_gait(rng) for _ in range(500)]
    for k, (lo, hi) in walk.GAIT_RANGES.items():
        v = np.array([d[k] for d in draws])
        assert v.min() >= lo and v.max() < hi
    assert 0 <= min(d["phase"] for d in draws) and max(d["phase"] for d in draws) < 1


def test_forward_kinematics_preserves_segment_lengths_and_heading():
    rng = np.random.default_rng(2)
    for _ in range(20):
        s = sample_subject(rng, "test")
        g = walk.sample_gait(rng)
        rest = walk.rest_skeleton(s)
        J = walk.skeleton_positions(s, g)
        for c in range(1, len(JOINT_NAMES)):
            p = PARENTS[c]
            assert np.linalg.norm(J[c] - J[p]) == pytest.approx(np.linalg.norm(rest[c] - rest[p]), abs=1e-12)
        np.testing.assert_allclose(J[0, :2], [g["x"], g["y"]], atol=1e-12)
        # the hips lie across the walking direction: (l_hip - r_hip) is the heading rotated by +90 deg,
        # up to the pelvis rotation
        d = J[JOINT_INDEX["l_hip"]] - J[JOINT_INDEX["r_hip"]]
        ang = np.arctan2(d[1], d[0]) - (g["heading"] + np.pi / 2)
        assert abs(np.angle(np.exp(1j * ang))) <= g["pelvis_rotation"] + 1e-9


def test_brute_force_fk_with_rotation_matrices():
    """Independent FK: rotate each subtree about its joint, bone by bone, from the root down."""
    rng = np.random.default_rng(3)
    s, g = sample_subject(rng, "train"), walk.sample_gait(rng)
    rest = walk.rest_skeleton(s)
    ang = walk.joint_angles(g)
    pts = rest.copy()
    # apply local rotations from the leaves up: each bone's rotation about its (rest) head, in
    # rest axes, to its subtree; applied leaf-first this equals the composed chain.
    def subtree(c):
        out = [c]
        for k in range(len(PARENTS)):
            if PARENTS[k] == c:
                out += subtree(k)
        return out
    for c in reversed(range(1, len(JOINT_NAMES))):
        R = walk.euler_matrix(ang[JOINT_NAMES[c]])
        idx = subtree(c)
        pivot = pts[PARENTS[c]]
        pts[idx] = (pts[idx] - pivot) @ R.T + pivot
    T = walk.root_transform(s, g)
    world = pts @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(world, walk.skeleton_positions(s, g), atol=1e-12)


def test_describe_distribution_matches_sampling_and_is_json():
    import json

    d = walk.describe_distribution()
    json.dumps(d)
    assert tuple(d["fields"]) == walk.GAIT_FIELDS
    for k, spec in d["fields"].items():
        assert (spec["low"], spec["high"]) == pytest.approx(walk.GAIT_RANGES[k])


def test_walkers_stand_inside_the_given_workspace_and_the_default_draws_are_unchanged():
    from silpose.shared.rig_frame import DEFAULT_WORKSPACE, Workspace

    # The built-in workspace gives exactly the draws of the former constant ranges (+-1.5 m).
    ref = np.random.default_rng(11)
    expected = [float(ref.uniform(*(walk.GAIT_RANGES[k] if k not in "xy" else (-1.5, 1.5)))) for k in walk.GAIT_FIELDS]
    assert list(walk.sample_gait(np.random.default_rng(11)).values()) == expected
    assert walk.sample_gait(np.random.default_rng(11), DEFAULT_WORKSPACE) == walk.sample_gait(np.random.default_rng(11))
    ws = Workspace([2.0, -3.0], [1.0, 0.5])
    rng = np.random.default_rng(12)
    xy = np.array([[g["x"], g["y"]] for g in (walk.sample_gait(rng, ws) for _ in range(300))])
    assert ws.contains(xy).all()
    assert xy[:, 0].max() - xy[:, 0].min() > 0.9 and xy[:, 1].max() - xy[:, 1].min() > 0.45  # the whole rectangle
    assert walk.describe_distribution(ws)["fields"]["x"]["low"] == 1.5


def test_person_height_of_the_workspace_checks_covers_every_configured_stature():
    from silpose.datagen.subjects import describe_distribution as subjects
    from silpose.shared.rig_frame import PERSON_HEIGHT_M

    tallest = max(subjects(s)["fields"]["height"]["high"] for s in ("train", "test"))
    assert tallest <= PERSON_HEIGHT_M < tallest + 0.05
