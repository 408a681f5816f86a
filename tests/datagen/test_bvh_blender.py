"""Motion-capture clips through Blender: a BVH written by the test (known skeleton, known
rotations), imported by Blender's own importer in a spawned worker, retargeted and rendered.

The reference is ``silpose.datagen.testing.synthetic_clip_positions``, a forward kinematics of the
BVH definition independent of Blender and of the retargeting. This process never imports bpy."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from silpose.datagen.motion.bvh_motion import BvhMotion
from silpose.datagen.motion.clips import ClipError, ensure_cached, read_entry
from silpose.datagen.config import load_config
from silpose.datagen.pipeline import generate
from silpose.datagen.scene import draw_scene
from silpose.datagen.subjects import segment_lengths
from silpose.datagen.testing import SYNTH_SKELETON, synthetic_clip_positions, write_synthetic_bvh
from silpose.datagen.validate import validate_dataset
from silpose.datagen.walk import euler_matrix, foot_points, rest_skeleton
from silpose.shared.dataset import load_split
from silpose.shared.skeleton import JOINT_NAMES, PARENTS

pytestmark = pytest.mark.blender

N_FRAMES = 4
CMU = [row[0] for row in SYNTH_SKELETON]


def _config(folder, clip: str, scale: float, name: str):
    path = folder / f"{name}.toml"
    path.write_text(f'name = "{name}"\nseed = 5\nrenderer = "raster"\nshard_size = 4\nn_points = 64\nmax_redraws = 30\n'
                    f'[splits]\ntrain = 6\ntest = 2\n[motion]\nsource = "bvh"\nbvh = ["{clip}"]\nscale = {scale}\n'
                    f'licence = "written by the test"\n')
    return load_config(path)


def _angle_deg(a, b):
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b))))


def _expected_world_direction(P, ends, name, heading, subject_split_fraction):
    """World direction of silpose bone ``name`` for clip frame P (J, 3) turned to ``heading``."""
    ix = {n: i for i, n in enumerate(CMU)}
    role = {"pelvis": "Hips", "neck": "Neck", "head": "Head", "l_shoulder": "LeftArm", "l_elbow": "LeftForeArm",
            "l_wrist": "LeftHand", "l_hip": "LeftUpLeg", "l_knee": "LeftLeg", "l_ankle": "LeftFoot",
            "l_toe": "LeftToeBase"}
    role.update({"r" + k[1:]: v.replace("Left", "Right") for k, v in role.items() if k.startswith("l_")})
    q = {k: P[ix[v]] for k, v in role.items()}
    chain = np.array([P[ix[n]] for n in ("Hips", "Spine", "Spine1", "Neck")])
    seg = np.linalg.norm(np.diff(chain, axis=0), axis=1)
    target, acc = subject_split_fraction * seg.sum(), 0.0
    for i, ln in enumerate(seg):
        if acc + ln >= target:
            spine = chain[i] + (target - acc) / ln * (chain[i + 1] - chain[i])
            break
        acc += ln
    parent_end = {"spine": q["pelvis"], "neck": spine, "head": q["neck"], "head_top": q["head"]}
    child_end = {"spine": spine, "neck": q["neck"], "head": q["head"], "head_top": ends[ix["Head"]]}
    if name in ("l_hip", "r_hip"):
        d = (q["l_hip"] - q["r_hip"]) * (1 if name[0] == "l" else -1)
    elif name in ("l_shoulder", "r_shoulder"):
        d = (q["l_shoulder"] - q["r_shoulder"]) * (1 if name[0] == "l" else -1)
    elif name in parent_end:
        d = child_end[name] - parent_end[name]
    else:
        parent = JOINT_NAMES[PARENTS[JOINT_NAMES.index(name)]]
        d = q[name] - q[parent]
    lateral = q["l_hip"] - q["r_hip"]
    yaw = np.arctan2(lateral[1], lateral[0]) - np.pi / 2
    return euler_matrix((0.0, 0.0, heading - yaw)) @ d


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SILPOSE_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache" / "bvh"


def test_clip_rendered_with_its_directions_and_the_subjects_lengths_same_with_1_or_2_workers(tmp_path, cache):
    clip_cm = write_synthetic_bvh(tmp_path / "synth_cmu_cm.bvh", "cmu", unit=0.01, n_frames=N_FRAMES)
    clip_m = write_synthetic_bvh(tmp_path / "synth_hk_m.bvh", "hip-knee", unit=1.0, n_frames=N_FRAMES)
    ref, ends = synthetic_clip_positions(N_FRAMES)

    # Blender's import equals the independent forward kinematics (file unit: centimetres)
    (sha, folder), = ensure_cached([clip_cm]).values()
    arrays = read_entry(folder)
    assert arrays.meta["names"][:5] == ["Hips", "Spine", "Spine1", "Neck", "Head"]
    order = [arrays.meta["names"].index(n) for n in CMU]
    np.testing.assert_allclose(arrays.heads[:, order] * 0.01, ref, atol=1e-5)
    head_end = np.asarray(arrays.tails[:, order[CMU.index("Head")]]) * 0.01
    np.testing.assert_allclose(head_end, ends[:, CMU.index("Head")], atol=1e-5)

    cfg = _config(tmp_path, clip_cm.name, 0.01, "cm")
    one = generate(cfg, tmp_path / "one", workers=1, progress=False)
    two = generate(cfg, tmp_path / "two", workers=2, progress=False)
    assert [s["sha256"] for s in one["shards"]] == [s["sha256"] for s in two["shards"]]
    assert one["config"]["motion"]["clips"][0]["sha256"] == sha
    assert one["config"]["motion"]["clips"][0]["frames"] == N_FRAMES

    report = validate_dataset(tmp_path / "one")
    assert report.ok, report.format()
    prepared = cfg.with_motion()
    motion = BvhMotion.from_config(prepared.worker_config()["motion"])
    for split in ("train", "test"):
        assert report.splits[split]["joints_inside"] == 1.0
        data = load_split(tmp_path / "one", split)
        for i in range(len(data)):
            frame, heading = int(data.gait["frame"][i]), float(data.gait["heading"][i])
            subject = {k: float(v[i]) for k, v in data.subject.items()}
            joints = data.joints[i].astype(np.float64)
            rest = rest_skeleton(subject)
            L = segment_lengths(subject)
            fraction = L["torso_lower"] / (L["torso_lower"] + L["torso_upper"])
            for c in range(1, 19):
                name, p = JOINT_NAMES[c], PARENTS[c]
                got = joints[c] - joints[p]
                assert np.linalg.norm(got) == pytest.approx(np.linalg.norm(rest[c] - rest[p]), abs=2e-4), name
                exp = _expected_world_direction(ref[frame], ends[frame], name, heading, fraction)
                assert _angle_deg(got, exp) <= 1.0, (split, i, name, _angle_deg(got, exp))
            # the pure pose (no Blender) is what Blender rendered, and its feet stand on the floor
            scene = draw_scene(5, split, int(data.sample_id[i]), int(data.extra["redraws"][i]), cfg.rig, motion)
            np.testing.assert_allclose(scene.pose.joints, joints, atol=2e-5)
            G = np.zeros((19, 3, 3))
            G[0] = np.eye(3)
            for c in range(1, 19):
                G[c] = G[PARENTS[c]] @ scene.pose.rotations[JOINT_NAMES[c]]
            body = (scene.pose.joints - scene.pose.root[:3, 3]) @ scene.pose.root[:3, :3]
            assert foot_points(scene.subject, body, G)[:, 2].min() + scene.pose.root[2, 3] == pytest.approx(0.0, abs=1e-9)

    # the same motion in the other naming scheme and unit gives the same dataset joints
    other = _config(tmp_path, clip_m.name, 1.0, "m")
    generate(other, tmp_path / "metres", workers=2, progress=False)
    for split in ("train", "test"):
        a, b = load_split(tmp_path / "one", split), load_split(tmp_path / "metres", split)
        np.testing.assert_allclose(a.joints, b.joints, atol=1e-4)
        np.testing.assert_array_equal(a.gait["frame"], b.gait["frame"])


def test_malformed_clips_fail_with_one_line_naming_the_file(tmp_path, cache):
    good = write_synthetic_bvh(tmp_path / "good.bvh").read_text()
    head, motion = good.split("MOTION\n")
    frames = motion.splitlines()[2:]
    words = tmp_path / "words.bvh"  # right token count, but not numbers: Blender's importer raises
    words.write_text(head + "MOTION\nFrames: 1\nFrame Time: 0.03\n" + " ".join(["abc"] * len(frames[0].split())) + "\n")
    with pytest.raises(ClipError) as err:
        ensure_cached([words])
    msg = str(err.value)
    assert msg.startswith(f"{words}: Blender's BVH importer failed (") and "\n" not in msg
    assert not list(cache.glob("*/meta.json"))

    truncated = tmp_path / "clips" / "truncated.bvh"
    truncated.parent.mkdir()
    truncated.write_text(head + "MOTION\nFrames: 4\nFrame Time: 0.03\n" + "\n".join(frames[:2]) + "\n")
    cfg = tmp_path / "cfg.toml"
    cfg.write_text('name = "bad"\nseed = 0\nrenderer = "raster"\nshard_size = 4\nn_points = 64\nmax_redraws = 5\n'
                   '[splits]\ntrain = 2\n[motion]\nsource = "bvh"\nbvh = ["clips/*.bvh"]\n')
    run = subprocess.run([sys.executable, "-m", "silpose.shared.cli", "gen", str(cfg), "--out", str(tmp_path / "ds"),
                          "--no-progress", "-j", "1"], capture_output=True, text=True, timeout=300)
    assert run.returncode != 0
    err_lines = [ln for ln in run.stderr.splitlines() if ln.strip()]
    assert err_lines == [f"silpose gen: error: {truncated}: MOTION has 2 frame lines but 'Frames: 4' (truncated file?)"]


def test_a_clip_saved_by_a_windows_editor_imports_as_the_same_motion(tmp_path, cache):
    """A byte-order mark and CRLF line ends (Notepad's save): Blender's importer would not read the marked first line
    as HIERARCHY; silpose gives it a copy without the mark, and the motion is the plain file's, value for value."""
    plain = write_synthetic_bvh(tmp_path / "plain.bvh")
    windows = tmp_path / "windows.bvh"
    windows.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes().replace(b"\n", b"\r\n"))
    entries = ensure_cached([plain, windows], workers=1)
    a, b = read_entry(entries[plain][1]), read_entry(entries[windows][1])
    assert entries[plain][0] != entries[windows][0]  # two files (their own checksums), one motion
    np.testing.assert_array_equal(np.asarray(a.heads), np.asarray(b.heads))
    np.testing.assert_array_equal(np.asarray(a.tails), np.asarray(b.tails))
