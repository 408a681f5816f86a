"""The bundled motion library, the ``library`` motion source and the ``motions`` preset (no Blender).

References are independent of the code under test: bone directions are compared with the
library's stored arrays read straight from the Parquet file, and pose variety is measured here
from the joints alone (a wrist above the neck; one ankle >= 35 cm above the other or both >= 20 cm
off the floor; the pelvis below 40 % of the head-top height; the trunk tilted > 35 deg).
"""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from silpose.datagen.config import load_config
from silpose.datagen.motion.config import MotionConfigError, motion_from_dict
from silpose.datagen.motion.library import (BUNDLED, CMU_ACKNOWLEDGEMENT, FRAMES_NAME, MANIFEST_NAME, PARENTS, ROLES,
                                            LibraryClip, LibraryError, derive, load_library, reconstruct, resample_chain,
                                            write_library)
from silpose.datagen.motion.mix import MIX_FIELDS, PART_FIELDS, SWING_FIELDS, MixedMotion, prepare_library
from silpose.datagen.motion.retarget import retarget_frame
from silpose.datagen.scene import draw_scene
from silpose.datagen.subjects import sample_subject
from silpose.shared.camera import default_rig
from silpose.shared.seeds import derive_rng
from silpose.shared.skeleton import JOINT_NAMES

J = {n: i for i, n in enumerate(JOINT_NAMES)}


def manifest():
    return json.loads((BUNDLED / MANIFEST_NAME).read_text())


# ----------------------------------------------------------------------------------- bundled data


def test_bundled_library_coverage_sources_and_size():
    m = manifest()
    clips = m["clips"]
    assert m["acknowledgement"] == CMU_ACKNOWLEDGEMENT
    assert len(clips) >= 60
    assert len({c["subject"] for c in clips}) >= 15
    assert len({c["group"] for c in clips}) >= 10
    for c in clips:
        assert c["licence"] and c["source"] and len(c["sha256"]) == 64 and c["description"]
        assert 15.0 <= c["fps"] <= 30.5 and c["frames"] > 0
        assert 1.2 <= c["extent_m"] <= 2.6, (c["id"], c["extent_m"])  # the unit (scale) is right
        subject, _trial = c["id"].removeprefix("cmu_").split("_")
        assert int(subject) == int(c["subject"]), c["id"]  # a CMU trial id names its subject
    assert len({c["id"] for c in clips}) == len(clips) and len({c["sha256"] for c in clips}) == len(clips)
    assert (BUNDLED / FRAMES_NAME).stat().st_size + (BUNDLED / MANIFEST_NAME).stat().st_size <= 40e6
    col = pq.ParquetFile(BUNDLED / FRAMES_NAME).read(columns=["clip"]).column("clip")
    # the int32 values straight from the Arrow buffers (to_numpy would import pandas: 4 s on a loaded machine)
    clip = np.concatenate([np.frombuffer(a.buffers()[1], np.int32)[a.offset:a.offset + len(a)] for a in col.chunks])
    assert np.array_equal(np.bincount(clip), [c["frames"] for c in clips])


def test_train_and_test_hold_out_subjects():
    clips = manifest()["clips"]
    train = {c["id"] for c in clips if c["split"] == "train"}
    test = {c["id"] for c in clips if c["split"] == "test"}
    assert train and test and not train & test and train | test == {c["id"] for c in clips}
    subj = {s: {c["subject"] for c in clips if c["split"] == s} for s in ("train", "test")}
    assert not subj["train"] & subj["test"]
    sha = {s: {c["sha256"] for c in clips if c["split"] == s} for s in ("train", "test")}
    assert not sha["train"] & sha["test"]


def test_every_group_has_training_and_test_subjects():
    clips = manifest()["clips"]
    for group in {c["group"] for c in clips}:
        for split in ("train", "test"):
            assert any(c["group"] == group and c["split"] == split for c in clips), (group, split)
    frames = {s: sum(c["frames"] for c in clips if c["split"] == s) for s in ("train", "test")}
    assert 0.2 <= frames["test"] / (frames["train"] + frames["test"]) <= 0.35, frames


def test_build_script_reproduces_the_bundled_manifest_rows(tmp_path):
    """cmu_sources on empty files laid out as the manifest's sources say gives the manifest's rows."""
    from silpose.datagen.motion import cmu_library as cl

    clips = manifest()["clips"]
    repos = {"iclone": cl.ICLONE, "bvh11": cl.BVH11, "cookbook": cl.COOKBOOK, "rgbd": cl.RGBD, "salsa": cl.SALSA,
             "makehuman": cl.MAKEHUMAN, "lawrence": cl.LAWRENCE}
    for c in clips:
        repo_at, path = c["source"].removeprefix("github.com/").split(":", 1)
        key = next(k for k, (name, commit) in repos.items() if repo_at == f"{name}@{commit[:7]}")
        (tmp_path / key / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / key / path).write_text("")
    rows = ["Subject,Trial #,Motion Description"] + [
        f'{int(c["id"].split("_")[1])},{int(c["id"].split("_")[2])},"{c["description"]}"' for c in clips]
    (tmp_path / "iclone" / "CMU data.csv").write_text("\n".join(rows) + "\n")
    got = cl.cmu_sources(*(tmp_path / k for k in repos))
    want = [(c["id"], c["subject"], c["description"], c["group"], c["split"], c["source"], c["joint_map"], c["scale"],
             c["first"], c["licence"]) for c in clips]
    assert [(s.id, s.subject, s.description, s.group, s.split, s.source, s.joint_map, s.scale, s.first, s.licence)
            for s in got] == want
    assert {c["subject"] for c in clips if c["split"] == "test"} == cl.TEST_SUBJECTS


# ------------------------------------------------------------------------------ form and retarget


def _rigid_positions(n=7, seed=1):
    """Role positions with constant segment lengths (a rigid skeleton in random poses)."""
    rng = np.random.default_rng(seed)
    lengths = rng.uniform(0.05, 0.5, len(ROLES) - 1)
    P = np.zeros((n, len(ROLES), 3))
    P[:, 0] = rng.normal(size=(n, 3))
    for c in range(1, len(ROLES)):
        d = rng.normal(size=(n, 3))
        P[:, c] = P[:, PARENTS[c]] + lengths[c - 1] * d / np.linalg.norm(d, axis=1, keepdims=True)
    return P, lengths


def test_derive_reconstruct_round_trip():
    P, lengths = _rigid_positions()
    root, dirs, got_lengths = derive(P)
    assert np.allclose(got_lengths, lengths)
    assert np.allclose(np.linalg.norm(dirs, axis=2), 1.0)
    assert np.allclose(reconstruct(root, dirs, got_lengths), P, atol=1e-12)


def test_spine_chain_with_a_zero_length_segment_is_resampled():
    up = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.1], [0.0, 0.0, 0.25], [0.0, 0.0, 0.4], [0.0, 0.0, 0.6]])
    assert np.array_equal(resample_chain(up[None]), up[None])  # five distinct points: kept as they are
    mb = up[[0, 0, 2, 3, 3]][None]  # LowerBack at the hips, Neck at Spine1 (MotionBuilder-friendly CMU)
    got = resample_chain(mb)[0]
    assert np.allclose(got[:, 2], [0.0, 0.1, 0.2, 0.3, 0.4])  # quarter points of the 0.4 m arc
    assert np.all(np.diff(got[:, 2]) > 0)  # every spine role has a direction


def _stored(lib_path):
    """Frames, clip rows and directions read straight from the Parquet file (the reference)."""
    t = pq.ParquetFile(lib_path / FRAMES_NAME).read()
    clip = t.column("clip").to_numpy()
    dirs = np.asarray(t.column("dirs").combine_chunks().flatten().to_numpy()).reshape(len(clip), -1, 3)
    return clip, dirs


#: silpose limb bone (parent joint, child joint); the library role of the same name as the child
#: stores the direction from the same parent.
LIMBS = [(f"{s}_{a}", f"{s}_{b}") for s in "lr" for a, b in (("shoulder", "elbow"), ("elbow", "wrist"),
                                                              ("hip", "knee"), ("knee", "ankle"))]


def _yaw_matrix(yaw):
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("group", sorted({c["group"] for c in manifest()["clips"]}))
def test_retargeting_keeps_each_clips_bone_directions(group):
    lib = load_library()
    clip_col, dirs = _stored(BUNDLED)
    rng = np.random.default_rng(0)
    subject = sample_subject(rng, "train")
    checked = 0
    for c, info in enumerate(lib.clips):
        if info["group"] != group:
            continue
        lc = LibraryClip(lib, c, 1.0)
        rows = np.flatnonzero(clip_col == c)
        for k in rng.choice(len(rows), size=min(3, len(rows)), replace=False):
            pts = lc.points(int(lc.used[k]), mirror=False)
            joints, _, yaw = retarget_frame(pts, subject)
            H = _yaw_matrix(yaw)
            for parent, child in LIMBS:
                got = joints[J[child]] - joints[J[parent]]
                want = H.T @ dirs[rows[k], ROLES.index(child) - 1].astype(np.float64)
                cos = got @ want / np.linalg.norm(got)
                assert cos > 1 - 1e-5, (info["id"], child, cos)
            checked += 1
    assert checked > 0


# ------------------------------------------------------------------------------------ the source


def test_mixed_motion_draws_only_its_splits_clips():
    motion = motion_from_dict({"source": "library", "procedural_walk": 0.2, "mirror": True}, BUNDLED, "t")
    prep = prepare_library(motion)
    clips = prep.clip_list()
    assert clips[0]["id"] == "procedural-walk" and all(c["split"] in ("train", "test") for c in clips[1:])
    worker = prep.worker()
    for split, walk_ok in (("train", True), ("test", False)):
        m = MixedMotion.from_config(worker, split)
        assert m.fields == MIX_FIELDS
        seen = set()
        for i in range(300):
            p = m.draw(derive_rng(7, 0, 0, i, 0))
            seen.add(int(p["clip"]))
            assert p == m.draw(derive_rng(7, 0, 0, i, 0))  # a pure function of its generator
        assert (0 in seen) == walk_ok
        assert all(clips[c]["split"] == split for c in seen if c)


def test_group_choice_and_errors():
    m = motion_from_dict({"source": "library", "groups": ["dance", "walk"], "weights": {"dance": 3}}, BUNDLED, "t")
    prep = prepare_library(m)
    assert {c["group"] for c in prep.clip_list()[1:]} <= {"dance", "walk"}
    bad = motion_from_dict({"source": "library", "groups": ["juggling"]}, BUNDLED, "cfg.toml")
    with pytest.raises(LibraryError, match="juggling"):
        prepare_library(bad)
    for raw, field in (({"source": "library", "procedural_walk": 2}, "procedural_walk"),
                       ({"source": "library", "weights": {"walk": -1}}, "weights"),
                       ({"source": "library", "bvh": ["x.bvh"]}, "bvh")):
        with pytest.raises(MotionConfigError, match=field):
            motion_from_dict(raw, BUNDLED, "cfg.toml")


def test_library_writer_refuses_foreign_folders_and_reader_checks_rows(tmp_path):
    (tmp_path / "mine.txt").write_text("not silpose's")
    P, _ = _rigid_positions(3)
    root, dirs, lengths = derive(P)
    arrays = [{"frame": np.arange(3), "root": root, "dirs": dirs, "lengths": lengths, "extent_m": 1.0}]
    row = [{"id": "a", "group": "walk", "split": "train", "licence": "x"}]
    with pytest.raises(LibraryError, match="did not write"):
        write_library(tmp_path, row, arrays)
    out = write_library(tmp_path / "lib", row, arrays)
    assert sorted(p.name for p in out.iterdir()) == [FRAMES_NAME, MANIFEST_NAME]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lib", "mine.txt"]  # no temporary left behind
    m = json.loads((out / MANIFEST_NAME).read_text())
    m["clips"][0]["frames"] = 4
    (out / MANIFEST_NAME).write_text(json.dumps(m))
    with pytest.raises(LibraryError, match="frame rows"):
        load_library(out)


# ------------------------------------------------------------------------------ the preset's poses


def variety(joints: np.ndarray) -> np.ndarray:
    """Independent pose-variety measure (module docstring): True per pose beyond walking."""
    z = joints[..., 2]
    wrist = np.maximum(z[:, J["l_wrist"]], z[:, J["r_wrist"]]) > z[:, J["neck"]]
    la, ra = z[:, J["l_ankle"]], z[:, J["r_ankle"]]
    feet = (np.abs(la - ra) >= 0.35) | ((la >= 0.20) & (ra >= 0.20))
    low = z[:, J["pelvis"]] < 0.4 * z[:, J["head_top"]]
    trunk = joints[:, J["neck"]] - joints[:, J["pelvis"]]
    tilt = trunk[:, 2] / np.linalg.norm(trunk, axis=1) < np.cos(np.radians(35))
    return wrist | feet | low | tilt


def _poses(preset, split, n):
    cfg = load_config(preset).with_motion()
    from silpose.datagen.worker import motion_from_config
    rig = default_rig()
    motion = motion_from_config(cfg.worker_config(), rig.workspace, split)
    scenes = [draw_scene(cfg.seed, split, i, 0, rig, motion) for i in range(n)]
    return np.stack([s.pose.joints for s in scenes]), scenes


def test_motions_preset_poses_go_beyond_walking_default_does_not():
    joints, scenes = _poses("motions", "train", 400)
    frac = variety(joints).mean()
    assert frac >= 0.35, frac
    walk, _ = _poses("default", "train", 200)
    assert variety(walk).mean() == 0.0
    assert any(s.motion["clip"] == 0 for s in scenes)  # the procedural walk is mixed in


SMALL = """name = "motions-small"
seed = 3
renderer = "raster"
shard_size = 6
n_points = 200
max_redraws = 50
[splits]
train = 12
test = 6
[motion]
source = "library"
procedural_walk = 0.2
mirror = true
part_mix = 0.5
limb_swing = 0.5
[motion.weights]
bend = 3.0
leap = 3.0
"""


def test_rendered_motions_dataset_validates_and_indexes_its_clip_list(tmp_path):
    from silpose.datagen.config import load_config as load
    from silpose.datagen.pipeline import generate
    from silpose.datagen.validate import validate_dataset
    from silpose.shared.dataset import list_shards, load_split, read_metadata

    (tmp_path / "small.toml").write_text(SMALL)
    generate(load(tmp_path / "small.toml"), tmp_path / "ds", workers=1, progress=False, preview=False, card=True)
    report = validate_dataset(tmp_path / "ds")
    assert report.ok, report.format()
    for s in report.splits.values():
        assert s["joints_inside"] == 1.0 and s["contour_dist_max"] <= 0.75
    for split in ("train", "test"):
        meta = read_metadata(list_shards(tmp_path / "ds", split)[0])["config"]["motion"]
        clips = meta["clips"]
        assert clips[0]["id"] == "procedural-walk" and {"id", "group", "split", "licence"} <= set(clips[1])
        gait = load_split(tmp_path / "ds", split, columns=["gait"]).gait
        idx = np.asarray(gait["clip"], int)
        assert set(gait) == set(MIX_FIELDS + PART_FIELDS + SWING_FIELDS) and np.all((idx >= 0) & (idx < len(clips)))
        swung = np.any([np.asarray(gait[k]) != 0 for k in SWING_FIELDS], axis=0)
        assert np.any(swung) if split == "train" else not np.any(swung)  # limb swing: training only
        legs = np.asarray(gait["legs_clip"], int)
        assert np.any(legs > 0) if split == "train" else np.all(legs == -1)  # part mixing: training only
        assert all(clips[i]["split"] == "train" for i in legs if i > 0)
        assert all(clips[i]["split"] == split for i in idx if i)  # held-out subjects' clips only in test
        if split == "test":
            assert not np.any(idx == 0)
    from silpose.datagen.preview import write_preview

    assert write_preview(tmp_path / "ds", tmp_path / "p.png", split="train").stat().st_size > 0  # part-mixed labels
    card = (tmp_path / "ds" / "README.md").read_text()
    assert CMU_ACKNOWLEDGEMENT in card and "| group | train clips | test clips |" in card and "Limb swing: 0.5" in card
