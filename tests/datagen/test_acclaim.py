"""ASF/AMC clips (the CMU database's own format), read by :mod:`silpose.datagen.motion.acclaim`.

References: Blender's own BVH importer run on a BVH file the test writes from the same skeleton and
motion (each bone's local rotation C M C^-1 turned into BVH Euler channels by scipy), scipy's
axis-angle rotations for the ASF ``axis`` frames, and plain arithmetic for units and axes."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from silpose.datagen.motion.acclaim import (CMU_FPS, INCH_M, AcclaimError, clip_sha256, read_clip, read_skeleton,
                                            skeleton_of)
from silpose.datagen.motion.clips import ClipError, ensure_cached, read_entry
from silpose.datagen.motion.joint_maps import resolve_map
from silpose.datagen.motion.library import FRAMES_NAME, MANIFEST_NAME, load_library

#: A CMU-shaped skeleton (bone, parent, direction (ASF, Y up), length (units), axis degrees XYZ, dof).
CMU_BONES = [
    ("lhipjoint", "root", (1.0, -0.9, 0.3), 1.7, (0, 0, -20), ()),
    ("lfemur", "lhipjoint", (0.2, -1.0, 0.0), 7.5, (0, 0, 20), ("rx", "ry", "rz")),
    ("ltibia", "lfemur", (0.0, -1.0, 0.05), 7.4, (0, 0, 20), ("rx",)),
    ("lfoot", "ltibia", (0.0, -0.3, 1.0), 2.3, (-90, 7, 20), ("rx", "rz")),
    ("ltoes", "lfoot", (0.0, 0.0, 1.0), 1.0, (-90, 7, 20), ("rx",)),
    ("lowerback", "root", (0.0, 1.0, 0.05), 2.0, (0, 0, 0), ("rx", "ry", "rz")),
    ("upperback", "lowerback", (0.0, 1.0, 0.0), 2.0, (0, 0, 0), ("rx", "ry", "rz")),
    ("thorax", "upperback", (0.0, 1.0, 0.0), 2.0, (0, 0, 0), ("rx", "ry", "rz")),
    ("lowerneck", "thorax", (0.0, 1.0, 0.1), 1.6, (0, 0, 0), ("rx", "ry", "rz")),
    ("upperneck", "lowerneck", (0.0, 1.0, 0.0), 1.6, (0, 0, 0), ("rx", "ry", "rz")),
    ("head", "upperneck", (0.0, 1.0, 0.0), 1.6, (0, 0, 0), ("rx", "ry", "rz")),
    ("lclavicle", "thorax", (1.0, 0.2, 0.0), 3.0, (0, 0, 0), ("ry", "rz")),
    ("lhumerus", "lclavicle", (1.0, 0.0, 0.0), 5.0, (0, 0, 90), ("rx", "ry", "rz")),
    ("lradius", "lhumerus", (1.0, 0.0, 0.0), 3.7, (0, 0, 90), ("rx",)),
    ("lwrist", "lradius", (1.0, 0.0, 0.0), 1.8, (0, 0, 90), ("ry",)),
    ("lhand", "lwrist", (1.0, 0.0, 0.0), 0.7, (0, 0, 90), ("rx", "rz")),
]
CMU_BONES += [("r" + n[1:] if n[0] == "l" else n, ("r" + p[1:]) if p[0] == "l" else p, (-d[0], d[1], d[2]), ln,
               (a[0], -a[1], -a[2]), dof) for n, p, d, ln, a, dof in CMU_BONES if n[0] == "l" and n != "lowerback"
              and n != "lowerneck"]
ROOT_ORDER = ("TX", "TY", "TZ", "RX", "RY", "RZ")
ORIENTATION = (0.0, 0.0, 0.0)
LENGTH_UNIT = 0.45


def write_asf(path, bones=CMU_BONES, length_unit=LENGTH_UNIT, orientation=ORIENTATION, angle="deg", extra=""):
    out = ["# written by the test", ":version 1.10", ":name VICON", ":units", "  mass 1.0",
           f"  length {length_unit}", f"  angle {angle}", ":documentation", "   a test skeleton", ":root",
           "   order " + " ".join(ROOT_ORDER), "   axis XYZ", "   position 0 0 0",
           "   orientation " + " ".join(str(v) for v in orientation), ":bonedata"]
    for k, (name, _, d, ln, axis, dof) in enumerate(bones, 1):
        u = np.asarray(d, float) / np.linalg.norm(d)
        out += ["  begin", f"     id {k}", f"     name {name}", "     direction " + " ".join(f"{v:.9f}" for v in u),
                f"     length {ln}", "     axis " + " ".join(str(v) for v in axis) + " XYZ"]
        if dof:
            out += ["    dof " + " ".join(dof), "    limits " + "\n           ".join("(-180.0 180.0)" for _ in dof)]
        out.append("  end")
    out += [":hierarchy", "  begin"]
    parents = ["root"] + [b[0] for b in bones]
    for p in parents:
        kids = [b[0] for b in bones if b[1] == p]
        if kids:
            out.append(f"    {p} " + " ".join(kids))
    out += ["  end", extra]
    path.write_text("\n".join(out) + "\n")
    return path


def motion(n_frames: int, seed: int = 0, bones=CMU_BONES):
    """Root (F, 6) in ROOT_ORDER (units, degrees) and {bone: (F, n_dof) degrees}."""
    rng = np.random.default_rng(seed)
    root = np.zeros((n_frames, 6))
    root[:, :3] = [0.0, 17.0, 0.0] + rng.uniform(-5, 5, (n_frames, 3)) * [1, 0.1, 1]
    root[:, 3:] = rng.uniform(-20, 20, (n_frames, 3)) * [1, 9, 1]
    return root, {b[0]: rng.uniform(-40, 40, (n_frames, len(b[5]))) for b in bones if b[5]}


def write_amc(path, root, values, bones=CMU_BONES, radians=False, skip=None):
    out = ["#!OML:ASF written by the test", ":FULLY-SPECIFIED", ":RADIANS" if radians else ":DEGREES"]
    k = np.deg2rad if radians else (lambda v: v)
    for f in range(len(root)):
        out.append(str(f + 1))
        out.append("root " + " ".join(f"{v:.6f}" for v in np.r_[root[f, :3], k(root[f, 3:])]))
        for name, *_ in bones:
            if name in values and (f, name) != skip:
                out.append(name + " " + " ".join(f"{v:.6f}" for v in k(values[name][f])))
    path.write_text("\n".join(out) + "\n")
    return path


def write_equivalent_bvh(path, root, values, bones=CMU_BONES, orientation=ORIENTATION):
    """The same skeleton and motion as a BVH file (file units): joint b's OFFSET is its parent bone's
    direction x length (0 for the root's children), its channels the local rotation C M C^-1 as
    intrinsic Z, X, Y Euler angles (scipy), leaf bones end in an End Site of their own length."""
    by = {b[0]: b for b in bones}
    kids = {p: [b[0] for b in bones if b[1] == p] for p in ["root"] + list(by)}

    def local(name, f):
        if name == "root":
            C = Rotation.from_euler("xyz", orientation, degrees=True)
            M = Rotation.from_euler("xyz", root[f, 3:], degrees=True)
        else:
            _, _, _, _, axis, dof = by[name]
            C = Rotation.from_euler("xyz", axis, degrees=True)
            M = Rotation.from_euler("".join(d[1] for d in dof), values[name][f], degrees=True) if dof else Rotation.identity()
        return (C * M * C.inv()).as_euler("ZXY", degrees=True)

    def vec(name):
        _, _, d, ln, _, _ = by[name]
        return np.asarray(d, float) / np.linalg.norm(d) * ln

    lines, order = ["HIERARCHY"], []

    def emit(name, depth):
        order.append(name)
        pad = "\t" * depth
        off = np.zeros(3) if name == "root" or by[name][1] == "root" else vec(by[name][1])
        lines.extend([f"{pad}{'ROOT' if name == 'root' else 'JOINT'} {name}", f"{pad}{{",
                      f"{pad}\tOFFSET " + " ".join(f"{v:.9f}" for v in off)])
        chans = ["Zrotation", "Xrotation", "Yrotation"]
        if name == "root":
            chans = ["Xposition", "Yposition", "Zposition"] + chans
        lines.append(f"{pad}\tCHANNELS {len(chans)} " + " ".join(chans))
        for k in kids.get(name, []):
            emit(k, depth + 1)
        if not kids.get(name) and name != "root":
            lines.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET " + " ".join(f"{v:.9f}" for v in vec(name)),
                          f"{pad}\t}}"])
        lines.append(f"{pad}}}")

    emit("root", 0)
    lines += ["MOTION", f"Frames: {len(root)}", "Frame Time: 0.0083333"]
    for f in range(len(root)):
        vals = list(root[f, :3])
        for name in order:
            vals += list(local(name, f))
        lines.append(" ".join(f"{v:.9f}" for v in vals))
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def clip(tmp_path):
    folder = tmp_path / "subjects" / "86"
    folder.mkdir(parents=True)
    write_asf(folder / "86.asf")
    root, values = motion(5)
    return write_amc(folder / "86_01.amc", root, values), root, values


@pytest.mark.blender
def test_positions_equal_blenders_import_of_the_same_motion_as_bvh(clip, tmp_path):
    amc, root, values = clip
    bvh = write_equivalent_bvh(tmp_path / "same.bvh", root, values)
    cache = tmp_path / "cache"
    entries = ensure_cached([amc, bvh], cache, workers=2)
    ours, blender = read_entry(entries[amc][1]), read_entry(entries[bvh][1])
    unit = INCH_M / LENGTH_UNIT
    assert ours.meta["names"][0] == "root" and sorted(ours.meta["names"]) == sorted(blender.meta["names"])
    b_index = {n: i for i, n in enumerate(blender.meta["names"])}
    order = [b_index[n] for n in ours.meta["names"]]
    ref_heads = np.asarray(blender.heads, np.float64)[:, order] * unit
    ref_tails = np.asarray(blender.tails, np.float64)[:, order] * unit
    assert np.abs(np.asarray(ours.heads) - ref_heads).max() < 1e-5  # metres; float32 and 9-digit files
    assert np.abs(np.asarray(ours.tails)[:, 1:] - ref_tails[:, 1:]).max() < 1e-5  # the root's tail is ours alone
    assert np.abs(np.asarray(ours.meta["rest_heads"]) - np.asarray(blender.meta["rest_heads"])[order] * unit).max() < 1e-6
    assert [ours.meta["names"][p] if p >= 0 else None for p in ours.meta["parents"]] == \
        [blender.meta["names"][blender.meta["parents"][i]] if blender.meta["parents"][i] >= 0 else None for i in order]
    assert ours.meta["frame_time"] == pytest.approx(1 / CMU_FPS) and ours.meta["frames"] == 5


def test_a_dof_turns_the_bone_about_its_axis_frames_own_axis(tmp_path):
    """rx of a bone whose axis is (30, -50, 70) turns its tail about C e_x through its head (scipy)."""
    bones = [("a", "root", (0.0, 1.0, 0.0), 4.0, (0, 0, 0), ()),
             ("b", "a", (1.0, 0.5, -0.2), 3.0, (30, -50, 70), ("rx",)),
             ("c", "b", (0.3, 0.0, 1.0), 2.0, (0, 0, 0), ())]
    folder = tmp_path / "s"
    folder.mkdir()
    write_asf(folder / "s.asf", bones=bones, length_unit=1.0)
    theta = np.array([0.0, 25.0, -70.0, 140.0])
    root = np.zeros((4, 6))
    meta, heads, tails = read_clip(write_amc(folder / "s_1.amc", root, {"b": theta[:, None]}, bones=bones))
    to_blender = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    axis = Rotation.from_euler("xyz", [30, -50, 70], degrees=True).apply([1.0, 0, 0])
    b_head = np.array([0.0, 4.0, 0.0])
    rest_c_tail = b_head + np.array([1.0, 0.5, -0.2]) / np.linalg.norm([1.0, 0.5, -0.2]) * 3.0 + \
        np.array([0.3, 0.0, 1.0]) / np.linalg.norm([0.3, 0.0, 1.0]) * 2.0
    ix = meta["names"].index("c")
    for f, t in enumerate(theta):
        expect = b_head + Rotation.from_rotvec(np.deg2rad(t) * axis).apply(rest_c_tail - b_head)
        assert np.allclose(tails[f, ix], (expect @ to_blender.T) * INCH_M, atol=1e-6)


def test_units_axes_and_radians(tmp_path):
    """A straight standing chain 10 units tall with length 0.45 is 10 x 0.0254 / 0.45 m tall, up the z
    axis; the same motion written in radians reads the same."""
    bones = [("up", "root", (0.0, 1.0, 0.0), 10.0, (0, 0, 0), ("rx",))]
    folder = tmp_path / "u"
    folder.mkdir()
    write_asf(folder / "u.asf", bones=bones)
    root = np.zeros((2, 6))
    root[1, 5] = 90.0  # root turned 90 degrees about the ASF z axis (forward): "up" now points along -x
    deg = read_clip(write_amc(folder / "u_1.amc", root, {"up": np.zeros((2, 1))}, bones=bones))
    tails = deg[2][:, 1]
    unit = INCH_M / 0.45
    assert np.allclose(tails[0], [0.0, 0.0, 10 * unit], atol=1e-6)
    assert np.allclose(tails[1], [-10 * unit, 0.0, 0.0], atol=1e-6)
    rad = read_clip(write_amc(folder / "u_2.amc", root, {"up": np.zeros((2, 1))}, bones=bones, radians=True))
    assert np.allclose(rad[2], deg[2], atol=1e-6)
    assert deg[0]["unit_m"] == pytest.approx(unit)


def test_the_cmu_skeleton_resolves_to_the_cmu_asf_map(clip):
    amc, *_ = clip
    meta, _, _ = read_clip(amc)
    jmap = resolve_map(meta["names"], meta["parents"], meta["rest_heads"], meta["rest_tails"], "auto", str(amc))
    names = meta["names"]
    assert jmap.name == "cmu-asf"
    assert names[jmap.index["neck"]] == "lowerneck" and names[jmap.index["l_shoulder"]] == "lhumerus"
    assert [names[i] for i in jmap.spine_chain] == ["root", "lowerback", "upperback", "thorax", "lowerneck"]
    assert jmap.head_tail  # the head bone points up from the neck
    rest = np.asarray(meta["rest_heads"])
    assert rest[jmap.index["head"], 2] > rest[jmap.index["neck"], 2] > rest[jmap.index["pelvis"], 2] > \
        rest[jmap.index["l_knee"], 2] > rest[jmap.index["l_ankle"], 2]  # z is up
    assert rest[jmap.index["l_hip"], 0] > 0 > rest[jmap.index["r_hip"], 0]


def test_bad_files_are_one_line_errors_naming_file_frame_and_bone(clip, tmp_path):
    amc, root, values = clip
    folder = amc.parent
    bad = write_amc(folder / "86_02.amc", root, values, skip=(3, "ltibia"))
    with pytest.raises(AcclaimError, match=r"86_02\.amc: frame 4 has no line for bone 'ltibia' \(is the file cut"):
        read_clip(bad)
    text = amc.read_text().replace("\nltibia ", "\nltibia 1.0 ", 1)
    (folder / "86_03.amc").write_text(text)
    with pytest.raises(AcclaimError, match=r"86_03\.amc: line \d+: frame 1: bone 'ltibia' has 2 values, its dof in 86\.asf has 1"):
        read_clip(folder / "86_03.amc")
    (folder / "86_04.amc").write_text(amc.read_text().replace("\nlhand ", "\nlpinky ", 1))
    with pytest.raises(AcclaimError, match=r"86_04\.amc: line \d+: bone 'lpinky' is not in the skeleton 86\.asf"):
        read_clip(folder / "86_04.amc")
    lone = tmp_path / "lone"
    lone.mkdir()
    (lone / "07_01.amc").write_text(amc.read_text())
    with pytest.raises(AcclaimError, match=r"07_01\.amc: no skeleton: put its \.asf file beside it \(CMU: 07\.asf\)"):
        read_clip(lone / "07_01.amc")
    write_asf(lone / "other.asf")
    assert skeleton_of(lone / "07_01.amc") == lone / "other.asf"  # the folder's only skeleton
    write_asf(lone / "third.asf")
    with pytest.raises(AcclaimError, match="2 .asf files beside it and none named 07.asf"):
        skeleton_of(lone / "07_01.amc")
    odd = tmp_path / "odd"
    odd.mkdir()
    write_asf(odd / "odd.asf", bones=[("a", "root", (0, 1, 0), 1.0, (0, 0, 0), ("rx", "l"))])
    with pytest.raises(AcclaimError, match=r"odd\.asf: bone 'a': dof 'l' is not supported"):
        read_skeleton(odd / "odd.asf")
    (odd / "text.asf").write_text("hello\n")
    with pytest.raises(AcclaimError, match=r"text\.asf: line 1: not an ASF file"):
        read_skeleton(odd / "text.asf")


def test_the_cache_key_covers_the_skeleton(clip, tmp_path):
    amc, *_ = clip
    before = clip_sha256(amc)
    asf = amc.parent / "86.asf"
    asf.write_text(asf.read_text().replace("length 7.5", "length 7.6"))
    assert clip_sha256(amc) != before
    with pytest.raises(ClipError, match="86_09.amc: clip file not found"):
        ensure_cached([amc.parent / "86_09.amc"], tmp_path / "cache")


def test_motions_import_reads_a_cmu_folder_of_asf_and_amc(clip, tmp_path):
    amc, root, values = clip
    folder = amc.parent
    root2, values2 = motion(13, seed=1)
    write_amc(folder / "86_02.amc", root2, values2)
    write_amc(folder / "86_03.amc", root2, values2, skip=(5, "lfemur"))  # cut short: skipped, the others go on
    lib = tmp_path / "lib"
    env = {**os.environ, "SILPOSE_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-m", "silpose.shared.cli", "motions", "import", str(tmp_path / "subjects"),
                        "--library", str(lib), "--subject", "auto", "--group", "walk", "-j", "1"],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    skipped = [ln for ln in r.stderr.splitlines() if ln.startswith("skipped: ")]
    assert len(skipped) == 1 and "86_03.amc: frame 6 has no line for bone 'lfemur'" in skipped[0], r.stderr
    assert "2 clips imported, 1 skipped" in r.stdout
    assert sorted(p.name for p in lib.iterdir()) == [FRAMES_NAME, MANIFEST_NAME]
    m = json.loads((lib / MANIFEST_NAME).read_text())
    clips = {c["id"]: c for c in m["clips"]}
    assert sorted(clips) == ["86_01", "86_02"]
    assert {c["joint_map"] for c in clips.values()} == {"cmu-asf"}
    assert {c["subject"] for c in clips.values()} == {"86"}  # --subject auto: the name before '_'
    assert clips["86_02"]["source_fps"] == 120.0 and clips["86_02"]["stride"] == 4  # 120 fps thinned to 30
    assert clips["86_02"]["frames"] == 4  # frames 0, 4, 8, 12 of 13
    library = load_library(lib)
    rows = library.rows(1 if library.clips[1]["id"] == "86_02" else 0)
    assert np.all(np.isfinite(library.dirs[rows])) and len(library.frame[rows]) == 4


def test_import_reports_progress_over_the_files_it_reads_and_none_when_cached(clip, tmp_path):
    amc, root, values = clip
    write_amc(amc.parent / "86_02.amc", *motion(3, seed=2))
    write_amc(amc.parent / "86_03.amc", root, values, skip=(1, "lfoot"))  # fails: still counted
    from silpose.datagen.motion.build import ClipSource, import_clips

    sources = [ClipSource(path=p, subject="86") for p in sorted(amc.parent.glob("*.amc"))]
    calls: list[tuple[int, int]] = []
    report = import_clips(sources, tmp_path / "lib", workers=1, cache=tmp_path / "cache",
                          progress=lambda d, t: calls.append((d, t)))
    assert calls == [(0, 3), (1, 3), (2, 3), (3, 3)] and len(report.added) == 2 and len(report.skipped) == 1
    calls.clear()
    import_clips(sources[:2], tmp_path / "lib", workers=1, cache=tmp_path / "cache", progress=lambda d, t: calls.append((d, t)))
    assert calls == [(0, 0)]  # both in the cache: nothing to read


def test_subject_auto_reads_the_cmu_name():
    from pathlib import Path

    from silpose.datagen.motion.cli import subject_of

    assert subject_of(Path("x/02_01.amc")) == "2" and subject_of(Path("143_12.bvh")) == "143"
    assert subject_of(Path("walk_fast.fbx")) == "walk" and subject_of(Path("idle.glb")) == "idle"
