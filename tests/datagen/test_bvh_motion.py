"""Motion-capture clips without Blender: joint maps, retargeting, the [motion] config, the BVH
structure checks and the motion source's draws.

The clip is ``silpose.datagen.testing``'s known skeleton; its joint positions come from that
module's own forward kinematics of the BVH definition (independent of the retargeting code)."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.datagen.motion.bvh_check import BvhError, check_structure
from silpose.datagen.config import ConfigError, load_config
from silpose.datagen.motion.joint_maps import BUILTIN_MAPS, REQUIRED_ROLES, JointMapError, load_map_file, resolve_map
from silpose.datagen.motion.config import CMU_SCALE
from silpose.datagen.motion.retarget import clip_points, heading_of, polyline_point, retarget_frame, swing
from silpose.datagen.subjects import segment_lengths
from silpose.datagen.testing import SYNTH_SKELETON, synthetic_clip_positions, write_synthetic_bvh
from silpose.datagen.walk import rest_skeleton
from silpose.shared.seeds import derive_rng
from silpose.shared.skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS, mirror_indices

SUBJECT = {"height": 1.8, "r_ankle": 0.039, "r_shank": 0.246, "r_thigh": 0.245, "r_torso_lower": 0.15,
           "r_torso_upper": 0.138, "r_neck": 0.062, "r_head": 0.12, "r_upper_arm": 0.186, "r_forearm": 0.146,
           "r_foot": 0.152, "r_shoulder_width": 0.259, "r_hip_width": 0.191, "g_torso": 1.0, "g_limbs": 1.0,
           "g_head": 1.0, "skirt_length": 0.0, "skirt_flare": 0.0, "trouser_width": 0.0, "hair_volume": 0.0,
           "hair_length": 0.0}
CMU = [row[0] for row in SYNTH_SKELETON]
HK = [row[1] for row in SYNTH_SKELETON]
PARENT_IDX = [row[2] for row in SYNTH_SKELETON]


def _rest():
    pos, end = synthetic_clip_positions(1)
    heads = pos[0]
    tails = np.where(np.isnan(end[0]), heads, end[0])
    return heads, tails


def _angle_deg(a, b):
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b))))


def _expected_directions(P, cmu_index, subject):
    """The documented directions of every silpose bone in the clip frame P (J, 3), body frame."""
    q = dict(pelvis=P[cmu_index["Hips"]], neck=P[cmu_index["Neck"]], head=P[cmu_index["Head"]])
    names = {"l_shoulder": "LeftArm", "l_elbow": "LeftForeArm", "l_wrist": "LeftHand", "l_hip": "LeftUpLeg",
             "l_knee": "LeftLeg", "l_ankle": "LeftFoot", "l_toe": "LeftToeBase"}
    for k, v in names.items():
        q[k] = P[cmu_index[v]]
        q["r" + k[1:]] = P[cmu_index[v.replace("Left", "Right")]]
    lateral = q["l_hip"] - q["r_hip"]
    yaw = np.arctan2(lateral[1], lateral[0]) - np.pi / 2
    c, s = np.cos(-yaw), np.sin(-yaw)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    chain = np.array([P[cmu_index[n]] for n in ("Hips", "Spine", "Spine1", "Neck")])
    L = segment_lengths(subject)
    t = L["torso_lower"] / (L["torso_lower"] + L["torso_upper"])
    seg = np.linalg.norm(np.diff(chain, axis=0), axis=1)
    target, acc, spine = t * seg.sum(), 0.0, None
    for i, ln in enumerate(seg):  # arc-length interpolation, written out
        if acc + ln >= target:
            spine = chain[i] + (target - acc) / ln * (chain[i + 1] - chain[i])
            break
        acc += ln
    d = {"spine": spine - q["pelvis"], "neck": q["neck"] - spine, "head": q["head"] - q["neck"],
         "l_hip": lateral, "r_hip": -lateral, "l_shoulder": q["l_shoulder"] - q["r_shoulder"],
         "r_shoulder": q["r_shoulder"] - q["l_shoulder"]}
    for side in "lr":
        d[f"{side}_elbow"] = q[f"{side}_elbow"] - q[f"{side}_shoulder"]
        d[f"{side}_wrist"] = q[f"{side}_wrist"] - q[f"{side}_elbow"]
        d[f"{side}_knee"] = q[f"{side}_knee"] - q[f"{side}_hip"]
        d[f"{side}_ankle"] = q[f"{side}_ankle"] - q[f"{side}_knee"]
        d[f"{side}_toe"] = q[f"{side}_toe"] - q[f"{side}_ankle"]
    return {k: Rz @ v for k, v in d.items()}, yaw


def test_retargeted_joints_have_the_clips_directions_and_the_subjects_lengths():
    pos, ends = synthetic_clip_positions(4)
    heads0, tails0 = _rest()
    jm = resolve_map(CMU, PARENT_IDX, heads0, tails0, "auto", "synth.bvh")
    assert jm.name == "cmu" and jm.head_tail
    assert [CMU[i] for i in jm.spine_chain] == ["Hips", "Spine", "Spine1", "Neck"]
    rest = rest_skeleton(SUBJECT)
    cmu_index = {n: i for i, n in enumerate(CMU)}
    for f in range(4):
        tails = np.where(np.isnan(ends[f]), pos[f], ends[f])
        J, G, yaw = retarget_frame(clip_points(pos[f], tails, jm, mirror=False), SUBJECT)
        expected, yaw_ref = _expected_directions(pos[f], cmu_index, SUBJECT)
        assert yaw == pytest.approx(yaw_ref, abs=1e-12)
        for c in range(1, 19):
            name, p = JOINT_NAMES[c], PARENTS[c]
            got = J[c] - J[p]
            assert np.linalg.norm(got) == pytest.approx(np.linalg.norm(rest[c] - rest[p]), abs=1e-9), name
            if name == "head_top":  # the head bone's End Site
                exp = (ends[f, cmu_index["Head"]] - pos[f, cmu_index["Head"]])
                c_, s_ = np.cos(-yaw), np.sin(-yaw)
                exp = np.array([[c_, -s_, 0], [s_, c_, 0], [0, 0, 1]]) @ exp
            else:
                exp = expected[name]
            assert _angle_deg(got, exp) < 1e-6, (f, name)
            np.testing.assert_allclose(G[c].T @ G[c], np.eye(3), atol=1e-9)
        assert J[0] == pytest.approx(rest[0])


def test_mirrored_frame_is_the_reflected_pose_with_sides_swapped():
    pos, ends = synthetic_clip_positions(4)
    heads0, tails0 = _rest()
    jm = resolve_map(CMU, PARENT_IDX, heads0, tails0, "cmu", "synth.bvh")
    for f in (1, 2, 3):
        tails = np.where(np.isnan(ends[f]), pos[f], ends[f])
        J, _, _ = retarget_frame(clip_points(pos[f], tails, jm, mirror=False), SUBJECT)
        Jm, _, _ = retarget_frame(clip_points(pos[f], tails, jm, mirror=True), SUBJECT)
        reflected = J[mirror_indices()] * np.array([1.0, -1.0, 1.0])  # body frame: reflect y, swap sides
        np.testing.assert_allclose(Jm, reflected, atol=1e-9)


def test_a_clip_without_toes_keeps_the_subjects_foot():
    pos, ends = synthetic_clip_positions(3)
    keep = [i for i, n in enumerate(CMU) if "Toe" not in n]
    names = [CMU[i] for i in keep]
    parents = [keep.index(PARENT_IDX[i]) if PARENT_IDX[i] >= 0 else -1 for i in keep]
    heads0, tails0 = _rest()
    jm = resolve_map(names, parents, heads0[keep], tails0[keep], "cmu", "notoe.bvh")
    assert jm.index["l_toe"] == -1 and jm.index["r_toe"] == -1
    J, G, _ = retarget_frame(clip_points(pos[2][keep], pos[2][keep], jm, False), SUBJECT)
    for side in "lr":
        a, t = JOINT_INDEX[f"{side}_ankle"], JOINT_INDEX[f"{side}_toe"]
        np.testing.assert_allclose(G[t], G[a], atol=1e-12)  # the foot turns with the shank only


def test_units_do_not_change_the_directions():
    pos, ends = synthetic_clip_positions(3)
    heads0, tails0 = _rest()
    jm = resolve_map(CMU, PARENT_IDX, heads0, tails0, "cmu", "a.bvh")
    tails = np.where(np.isnan(ends[2]), pos[2], ends[2])
    J1, _, _ = retarget_frame(clip_points(pos[2], tails, jm, False), SUBJECT)
    J2, _, _ = retarget_frame(clip_points(pos[2] * 100.0, tails * 100.0, jm, False), SUBJECT)
    np.testing.assert_allclose(J1, J2, atol=1e-12)


def test_swing_polyline_heading_helpers():
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = rng.normal(size=3), rng.normal(size=3)
        a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
        R = swing(a, b)
        np.testing.assert_allclose(R @ a, b, atol=1e-12)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(swing(np.array([0, 0, 1.0]), np.array([0, 0, -1.0])) @ [0, 0, 1.0], [0, 0, -1.0], atol=1e-12)
    pts = np.array([[0, 0, 0], [0, 0, 1.0], [0, 1.0, 1.0]])
    np.testing.assert_allclose(polyline_point(pts, 0.25), [0, 0, 0.5])
    np.testing.assert_allclose(polyline_point(pts, 0.75), [0, 0.5, 1.0])
    assert heading_of(np.array([0.0, 1.0, 0.0])) == pytest.approx(0.0)  # left = +y: facing +x
    assert heading_of(np.array([-1.0, 0.0, 0.3])) == pytest.approx(np.pi / 2)


# -- joint maps ---------------------------------------------------------------------------------

def test_auto_detects_every_builtin_scheme_and_names_the_file_otherwise():
    heads0, tails0 = _rest()
    assert resolve_map(HK, PARENT_IDX, heads0, tails0, "auto", "x.bvh").name == "hip-knee"
    for scheme, table in BUILTIN_MAPS.items():
        inverse = {v: k for k, v in table.items()}
        cmu_role = {v: k for k, v in BUILTIN_MAPS["cmu"].items()}
        names = [table.get(cmu_role.get(n), f"extra_{n}") for n in CMU]  # same skeleton, renamed
        if "head_top" in table:
            names[CMU.index("Head")] = table["head"]
        jm = resolve_map(names, PARENT_IDX, heads0, tails0, "auto", "x.bvh")
        assert jm.name == scheme, scheme
        assert all(names[jm.index[r]] == table[r] for r in REQUIRED_ROLES) and inverse
    renamed = [f"bone{i}" for i in range(len(CMU))]
    with pytest.raises(JointMapError) as err:
        resolve_map(renamed, PARENT_IDX, heads0, tails0, "auto", "/data/odd.bvh")
    msg = str(err.value)
    assert msg.startswith("/data/odd.bvh: joint names match no built-in map") and "\n" not in msg
    assert "joint_map" in msg


def test_user_map_file(tmp_path):
    heads0, tails0 = _rest()
    renamed = [f"bone{i}" for i in range(len(CMU))]
    table = {r: renamed[CMU.index(BUILTIN_MAPS["cmu"][r])] for r in REQUIRED_ROLES}
    path = tmp_path / "map.toml"
    path.write_text("".join(f'{k} = "{v}"\n' for k, v in table.items()))
    jm = resolve_map(renamed, PARENT_IDX, heads0, tails0, str(path), "odd.bvh")
    assert jm.index["l_knee"] == CMU.index("LeftLeg") and jm.index["l_toe"] == -1
    path.write_text('pelvis = "bone0"\nelbow = "x"\n')
    with pytest.raises(JointMapError, match=r"map.toml: field 'elbow': unknown silpose joint"):
        load_map_file(path)
    path.write_text('pelvis = "bone0"\n')
    with pytest.raises(JointMapError, match=r"map.toml: field 'neck' missing"):
        load_map_file(path)
    table["l_knee"] = "nope"
    path.write_text("".join(f'{k} = "{v}"\n' for k, v in table.items()))
    with pytest.raises(JointMapError, match=r"^odd.bvh: joint map .*'nope' \(silpose l_knee\) not in the clip"):
        resolve_map(renamed, PARENT_IDX, heads0, tails0, str(path), "odd.bvh")


# -- malformed files (the checks made before Blender's importer sees them) ---------------------------

def _variants(tmp_path):
    good = write_synthetic_bvh(tmp_path / "good.bvh").read_text()
    head, motion = good.split("MOTION\n")
    frames = motion.splitlines()[2:]
    n = len(frames[0].split())
    return good, head, frames, n


@pytest.mark.parametrize("case, pattern", [
    ("truncated_lines", r"MOTION has 2 frame lines but 'Frames: 4' \(truncated file\?\)"),
    ("truncated_line", r"line \d+ \(frame 3\): 5 values, the hierarchy declares {n} channels"),
    ("extra_values", r"line \d+ \(frame 0\): {m} values, the hierarchy declares {n} channels"),
    ("channel_count", r"line \d+: CHANNELS declares 6 channels but names 3"),
    ("zero_frames", r"no motion frames \(Frames: 0, 0 motion lines\)"),
    ("not_bvh", r"not a BVH file"),
    ("no_motion", r"no MOTION section"),
])
def test_malformed_files_give_one_line_naming_the_file(tmp_path, case, pattern):
    good, head, frames, n = _variants(tmp_path)
    text = {
        "truncated_lines": head + "MOTION\nFrames: 4\nFrame Time: 0.0333\n" + "\n".join(frames[:2]) + "\n",
        "truncated_line": head + "MOTION\nFrames: 4\nFrame Time: 0.0333\n" + "\n".join(frames[:3]) + "\n"
        + " ".join(frames[3].split()[:5]) + "\n",
        "extra_values": head + "MOTION\nFrames: 4\nFrame Time: 0.0333\n" + "\n".join(f + " 0.5 0.5" for f in frames) + "\n",
        "channel_count": good.replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 6 Zrotation Xrotation Yrotation", 1),
        "zero_frames": head + "MOTION\nFrames: 0\nFrame Time: 0.0333\n",
        "not_bvh": "this is not a motion file\n",
        "no_motion": head,
    }[case]
    path = tmp_path / f"{case}.bvh"
    path.write_text(text)
    with pytest.raises(BvhError) as err:
        check_structure(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"{path}: ")
    import re
    assert re.search(pattern.format(n=n, m=n + 2), msg), msg
    s = check_structure(write_synthetic_bvh(tmp_path / "ok.bvh"))
    assert (s.channels, s.frames) == (n, 4)


# -- the [motion] config -------------------------------------------------------------------------

BASE = 'name = "m"\nseed = 1\nrenderer = "raster"\nshard_size = 4\nn_points = 64\nmax_redraws = 20\n[splits]\ntrain = 4\n'


def test_motion_config(tmp_path):
    (tmp_path / "clips").mkdir()
    for name in ("b.bvh", "a.bvh", "c.bvh"):
        write_synthetic_bvh(tmp_path / "clips" / name)
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(BASE + '[motion]\nsource = "bvh"\nbvh = ["clips/*.bvh"]\nscale = 0.056444\nmirror = true\n'
                   'licence = "test clips"\n[[motion.clip]]\nfile = "clips/c.bvh"\nweight = 3.0\nframes = [1, -1]\n'
                   'note = "heavier"\n')
    m = load_config(cfg).motion
    assert m.is_bvh and m.mirror
    assert [c.file for c in m.clips] == ["clips/a.bvh", "clips/b.bvh", "clips/c.bvh"]
    assert [c.weight for c in m.clips] == [1.0, 1.0, 3.0]
    assert m.clips[2].frames == (1, -1) and m.clips[0].frames == (0, -1)
    assert m.clips[0].scale == pytest.approx(CMU_SCALE, rel=1e-5) and m.clips[2].note == "heavier"
    assert m.clips[1].licence == "test clips" and m.clips[2].licence == "test clips"
    with pytest.raises(ValueError, match="with_motion"):
        load_config(cfg).to_dict()
    plain = tmp_path / "plain.toml"
    plain.write_text(BASE + '[motion]\nsource = "procedural"\n')
    nomotion = tmp_path / "none.toml"
    nomotion.write_text(BASE)
    assert load_config(plain).to_dict() == load_config(nomotion).to_dict()
    assert load_config(plain).worker_config() == load_config(nomotion).worker_config()


@pytest.mark.parametrize("motion, pattern", [
    ('source = "mocap"', r"field 'source' must be one of procedural, bvh"),
    ('source = "bvh"', r"needs clips"),
    ('source = "bvh"\nbvh = ["nothing/*.bvh"]', r"field 'bvh': 'nothing/\*.bvh' matches no file"),
    ('source = "bvh"\nbvh = ["clips/*.bvh"]\nscale = -1', r"field 'scale' must be a number > 0"),
    ('source = "bvh"\nbvh = ["clips/*.bvh"]\nframes = [1]', r"field 'frames' must be \[first, last\]"),
    ('source = "bvh"\nbvh = ["clips/*.bvh"]\njoint_map = "missing.toml"', r"field 'joint_map': .*missing.toml: joint map file not found"),
    ('source = "bvh"\nbvh = ["clips/*.bvh"]\nspeed = 2', r"unknown field\(s\) speed"),
    ('mirror = true', r"field 'mirror' needs source = \"bvh\""),
    ('source = "bvh"\n[[motion.clip]]\nweight = 2.0', r"motion.clip\[0\]: field 'file' missing"),
])
def test_motion_config_errors_name_the_file_and_field(tmp_path, motion, pattern):
    (tmp_path / "clips").mkdir()
    write_synthetic_bvh(tmp_path / "clips" / "a.bvh")
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(BASE + "[motion]\n" + motion + "\n")
    with pytest.raises(ConfigError) as err:
        load_config(cfg)
    msg = str(err.value)
    assert msg.startswith(f"{cfg}: motion") and "\n" not in msg
    import re
    assert re.search(pattern, msg), msg


# -- the motion source's draws ------------------------------------------------------------------

class _Clip:
    def __init__(self, n, weight):
        self.used = np.arange(n)
        self.weight = weight


def test_draws_follow_the_weights_and_the_motion_stream():
    from silpose.datagen.motion.bvh_motion import BvhMotion
    from silpose.datagen.scene import draw_sample_parameters
    from silpose.datagen.walk import GAIT_FIELDS

    motion = BvhMotion([_Clip(10, 1.0), _Clip(30, 1.0), _Clip(10, 4.0)], mirror=True)
    rng = derive_rng(5)
    draws = [motion.draw(rng) for _ in range(6000)]
    counts = np.bincount([int(d["clip"]) for d in draws], minlength=3) / len(draws)
    np.testing.assert_allclose(counts, [10 / 80, 30 / 80, 40 / 80], atol=0.02)
    assert 0.45 < np.mean([d["mirror"] for d in draws]) < 0.55
    assert all(0 <= d["frame"] < (30 if d["clip"] == 1 else 10) for d in draws)
    assert set(draws[0]) == set(motion.fields)
    no_mirror = BvhMotion([_Clip(10, 1.0)], mirror=False)
    assert all(no_mirror.draw(rng)["mirror"] == 0.0 for _ in range(50))
    # subjects come from the sample draw (same bodies as the walk), motion from its own stream
    subj_bvh, params = draw_sample_parameters(3, "train", 7, 0, motion)
    subj_walk, gait = draw_sample_parameters(3, "train", 7, 0)
    assert subj_bvh == subj_walk and set(gait) == set(GAIT_FIELDS)
    from silpose.shared.seeds import MOTION_STREAM, SPLIT_CODE
    assert params == motion.draw(derive_rng(MOTION_STREAM, 3, SPLIT_CODE["train"], 7, 0))


# -- the clip table from a (pre-filled) import cache: no Blender needed -----------------------------

def _fill_cache(root, path, unit=0.01, n_frames=4):
    """Write the cache entry Blender's import would write for ``path`` (positions from the
    independent forward kinematics, in the file's unit)."""
    import json

    from silpose.datagen.motion.clips import entry_dir
    from silpose.datagen.manifest import sha256_file

    pos, ends = synthetic_clip_positions(n_frames)
    tails = np.where(np.isnan(ends), pos, ends)
    folder = entry_dir(root, sha256_file(path))
    folder.mkdir(parents=True)
    np.save(folder / "heads.npy", (pos / unit).astype(np.float32))
    np.save(folder / "tails.npy", (tails / unit).astype(np.float32))
    (folder / "meta.json").write_text(json.dumps({
        "names": CMU, "parents": PARENT_IDX, "frames": n_frames, "frame_time": 1 / 30,
        "rest_heads": (pos[0] / unit).tolist(), "rest_tails": (tails[0] / unit).tolist()}))
    return folder


def test_prepared_clips_record_their_identity_and_pose_subjects(tmp_path, monkeypatch):
    from silpose.datagen.motion.bvh_motion import BvhMotion
    from silpose.datagen.motion.clips import ClipError
    from silpose.datagen.manifest import sha256_file

    monkeypatch.setenv("SILPOSE_CACHE_DIR", str(tmp_path / "cache"))
    clip = write_synthetic_bvh(tmp_path / "walk.bvh", unit=0.01)
    _fill_cache(tmp_path / "cache" / "bvh", clip)
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(BASE + '[motion]\nsource = "bvh"\nbvh = ["walk.bvh"]\nscale = 0.01\nframes = [1, -1]\n'
                   'licence = "test licence"\n')
    prepared = load_config(cfg).with_motion()
    rec = prepared.to_dict()["motion"]["clips"][0]
    assert (rec["name"], rec["file"], rec["frames"], rec["used_frames"], rec["n_used"]) == ("walk", "walk.bvh", 4, [1, 3, 1], 3)
    assert rec["sha256"] == sha256_file(clip) and rec["joint_map"] == "cmu" and rec["licence"] == "test licence"
    assert 1.0 < rec["vertical_extent_m"] < 2.0  # the unit is right: a person-sized clip
    motion = BvhMotion.from_config(prepared.worker_config()["motion"])
    rng = derive_rng(1)
    for _ in range(5):
        params = motion.draw(rng)
        assert params["frame"] in (1.0, 2.0, 3.0) and params["mirror"] == 0.0
        pose = motion.pose(SUBJECT, params)
        rest = rest_skeleton(SUBJECT)
        for c in range(1, 19):
            assert np.linalg.norm(pose.joints[c] - pose.joints[PARENTS[c]]) == pytest.approx(
                np.linalg.norm(rest[c] - rest[PARENTS[c]]), abs=1e-9)
        assert pose.root[0, 3] == params["x"] and pose.root[1, 3] == params["y"]

    cfg.write_text(BASE + '[motion]\nsource = "bvh"\nbvh = ["walk.bvh"]\nframes = [2, 9]\n')
    with pytest.raises(ClipError, match=rf"^{clip}: frames \[2, 9\] are outside the clip's 4 frames \(0..3\)$"):
        load_config(cfg).with_motion()
    cfg.write_text(BASE + '[motion]\nsource = "bvh"\nbvh = ["walk.bvh"]\njoint_map = "bandai"\n')
    with pytest.raises(JointMapError, match=rf"^{clip}: joint map 'bandai': BVH joint 'UpperArm_L' \(silpose l_shoulder\) not in"):
        load_config(cfg).with_motion()
