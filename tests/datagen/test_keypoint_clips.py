"""Clips of joint keypoints (TRC files, ``silpose.datagen.motion.keypoint_clips``): a rigid-boned skeleton moved
by the test, written as TRC by the test's own writer (Y up, millimetres, Pose2Sim's marker names, gaps), read
back; imported into a library whose reconstructed role positions are the skeleton's; names, fallbacks, a Z-up
file stood up, one-line errors, and ``silpose motions import``."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from silpose.datagen.motion.build import ClipSource, import_clips
from silpose.datagen.motion.keypoint_clips import KeypointClipError, read_keypoint_clip, z_up_from_screen
from silpose.datagen.motion.library import ROLES as LIBRARY_ROLES
from silpose.datagen.motion.library import load_library

#: Pose2Sim's marker name of each role the test skeleton has
POSE2SIM = {"pelvis": "Hip", "neck": "Neck", "head": "Head", "l_shoulder": "LShoulder", "l_elbow": "LElbow",
            "l_wrist": "LWrist", "l_hip": "LHip", "l_knee": "LKnee", "l_ankle": "LAnkle", "l_toe": "LBigToe",
            "r_shoulder": "RShoulder", "r_elbow": "RElbow", "r_wrist": "RWrist", "r_hip": "RHip", "r_knee": "RKnee",
            "r_ankle": "RAnkle", "r_toe": "RBigToe"}
#: the skeleton: each role's parent and its rest offset from it, metres, Z up (x: the body's left)
BONES = {"pelvis": (None, (0.0, 0.0, 0.95)), "neck": ("pelvis", (0.0, 0.02, 0.5)), "head": ("neck", (0.0, 0.0, 0.2)),
         **{f"{s}_{j}": (p if p in ("pelvis", "neck") else f"{s}_{p}", (sign * dx, dy, dz))
            for s, sign in (("l", 1.0), ("r", -1.0))
            for j, p, dx, dy, dz in (("shoulder", "neck", 0.18, 0.0, -0.03), ("elbow", "shoulder", 0.02, 0.0, -0.28),
                                     ("wrist", "elbow", 0.0, 0.02, -0.25), ("hip", "pelvis", 0.09, 0.0, -0.05),
                                     ("knee", "hip", 0.0, 0.01, -0.42), ("ankle", "knee", 0.0, -0.02, -0.41),
                                     ("toe", "ankle", 0.0, 0.15, -0.06))}}


def skeleton_motion(n_frames: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Each role's (F, 3) positions, metres, Z up: every bone turned by its own rotation of up to 25 degrees per
    frame about its parent's end (so bone lengths are exact), the pelvis walking 1 m along y."""
    rng = np.random.default_rng(seed)
    out: dict[str, np.ndarray] = {}
    for role, (parent, offset) in BONES.items():
        turns = Rotation.from_rotvec(rng.uniform(-1, 1, (n_frames, 3)) * np.radians(25) / np.sqrt(3))
        if parent is None:
            out[role] = np.array(offset) + np.outer(np.linspace(0, 1, n_frames), [0.0, 1.0, 0.0])
        else:
            out[role] = out[parent] + turns.apply(np.array(offset))
    return out


def write_trc(path, positions: dict[str, np.ndarray], names: dict[str, str], rate: float = 30.0, unit: str = "mm",
              up: str = "y", gaps: dict[str, list[int]] | None = None, extra: dict[str, np.ndarray] | None = None):
    """The test's own TRC writer (OpenSim's layout): Y up by default, ``(x, y, z)`` Z up written ``(x, z, -y)``."""
    scale = {"mm": 1000.0, "m": 1.0, "cm": 100.0}[unit]
    tracks = {names[r]: p for r, p in positions.items() if r in names} | dict(extra or {})
    n = len(next(iter(tracks.values())))
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
             f"{rate}\t{rate}\t{n}\t{len(tracks)}\t{unit}\t{rate}\t1\t{n}",
             "Frame#\tTime\t" + "\t".join(f"{m}\t\t" for m in tracks).rstrip("\t"),
             "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, len(tracks) + 1)), ""]
    for f in range(n):
        cells = []
        for m, p in tracks.items():
            x, y, z = p[f] * scale
            xyz = (x, z, -y) if up == "y" else (x, y, z)
            cells += [""] * 3 if f in (gaps or {}).get(m, []) else [f"{v:.6f}" for v in xyz]
        lines.append(f"{f + 1}\t{f / rate:.6f}\t" + "\t".join(cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_reads_positions_in_metres_z_up_and_fills_gaps(tmp_path):
    pos = skeleton_motion(12)
    trc = write_trc(tmp_path / "a.trc", pos, POSE2SIM, gaps={"LWrist": [0, 5, 6], "RKnee": [11]},
                    extra={"RHeel": pos["r_ankle"] - [0, 0.05, 0], "*1": pos["head"], "*2": pos["neck"]})  # not read
    meta, heads, tails = read_keypoint_clip(trc)
    index = {r: i for i, r in enumerate(meta["names"])}
    assert set(index) == set(POSE2SIM) and meta["frames"] == 12 and meta["frame_time"] == pytest.approx(1 / 30)
    seen = np.ones(12, bool)
    for role in POSE2SIM:
        got = np.asarray(heads[:, index[role]], np.float64)
        keep = seen.copy()
        keep[{"l_wrist": [0, 5, 6], "r_knee": [11]}.get(role, [])] = False
        assert np.abs(got[keep] - pos[role][keep]).max() < 1e-6  # 6 decimals of a millimetre
    w = np.asarray(heads[:, index["l_wrist"]], np.float64)
    assert np.allclose(w[0], pos["l_wrist"][1], atol=1e-6)  # held before the first frame that sees it
    assert np.allclose(w[5], (2 * pos["l_wrist"][4] + pos["l_wrist"][7]) / 3, atol=1e-6)  # linear in time
    # a bone ends at its child's keypoint: the pelvis at the neck, the neck at the head, the knee at the ankle
    for role, child in (("pelvis", "neck"), ("neck", "head"), ("l_knee", "l_ankle")):
        assert np.allclose(tails[:, index[role]], heads[:, index[child]])
    parents = meta["parents"]
    assert meta["names"][parents[index["l_elbow"]]] == "l_shoulder" and parents[index["pelvis"]] == -1


@pytest.mark.parametrize("spelling", ["silpose", "coco"])
def test_other_spellings_and_the_missing_joints_from_their_neighbours(tmp_path, spelling):
    pos = skeleton_motion(4)
    if spelling == "silpose":  # silpose export --to trc: its own joint names, the pelvis and head top included
        names = {r: r for r in POSE2SIM}
        extra = {"spine": pos["neck"] * 0.5 + pos["pelvis"] * 0.5, "head_top": pos["head"] + [0, 0, 0.1]}
    else:  # COCO: no pelvis, neck or head; ears and a nose
        names = {r: f"{'left' if r[0] == 'l' else 'right'}_{r[2:]}" for r in POSE2SIM if r[1] == "_" and "toe" not in r}
        extra = {"left_ear": pos["head"] + [0.07, 0, 0], "right_ear": pos["head"] - [0.07, 0, 0],
                 "nose": pos["head"] + [0, 0.1, 0]}
    meta, heads, _ = read_keypoint_clip(write_trc(tmp_path / "b.trc", pos, names, unit="m", extra=extra))
    index = {r: i for i, r in enumerate(meta["names"])}
    h = lambda r: np.asarray(heads[:, index[r]], np.float64)  # noqa: E731
    if spelling == "silpose":
        assert "head_top" in index and np.allclose(h("head_top"), pos["head"] + [0, 0, 0.1], atol=1e-6)
        assert np.allclose(h("pelvis"), pos["pelvis"], atol=1e-6)
    else:
        assert np.allclose(h("pelvis"), 0.5 * (pos["l_hip"] + pos["r_hip"]), atol=1e-6)
        assert np.allclose(h("neck"), 0.5 * (pos["l_shoulder"] + pos["r_shoulder"]), atol=1e-6)
        assert np.allclose(h("head"), pos["head"], atol=1e-6)  # the ears' midpoint, not the nose
        assert "l_toe" not in index


def test_a_library_of_the_clip_holds_its_poses_and_a_z_up_file_is_stood_up(tmp_path):
    pos = skeleton_motion(20, seed=3)
    (tmp_path / "y").mkdir()
    (tmp_path / "z").mkdir()
    y_up = write_trc(tmp_path / "y" / "walk.trc", pos, POSE2SIM)
    z_up = write_trc(tmp_path / "z" / "walk.trc", pos, POSE2SIM, up="z")  # the same motion written Z up
    for i, trc in enumerate((y_up, z_up)):
        report = import_clips([ClipSource(path=trc, subject="s", group="walk")], tmp_path / f"lib{i}", workers=1,
                              cache=tmp_path / "cache")
        assert report.added == ["walk"] and not report.skipped
        lib = load_library(tmp_path / f"lib{i}")
        clip = lib.clips[0]
        assert clip["joint_map"] == "keypoints" and clip["fps"] == 30.0 and clip["frames"] == 20
        got = lib.positions(0)  # (F, 21, 3) from the stored root motion, directions and median lengths
        for role in POSE2SIM:
            assert np.abs(got[:, LIBRARY_ROLES.index(role)] - pos[role]).max() < 2e-5, (trc, role)
    assert json.loads((tmp_path / "lib1" / "manifest.json").read_text())["clips"][0]["rest_up"] == "-y"


def write_c3d(path, positions: dict[str, np.ndarray], names: dict[str, str], rate: float = 30.0,
              screen=("+X", "+Y"), unvisited: dict[str, list[int]] | None = None):
    """A C3D file through the c3d library's writer: millimetres, Y up by default (``(x, y, z)`` Z up written
    ``(x, z, -y)``), a point with residual -1 where not seen."""
    import c3d

    tracks = {names[r]: p for r, p in positions.items() if r in names}
    writer = c3d.Writer(point_rate=rate, point_scale=-1.0, point_units="mm  ")
    writer.set_point_labels(list(tracks))
    writer.set_screen_axis(X=screen[0], Y=screen[1])
    frames = []
    for f in range(len(next(iter(tracks.values())))):
        pts = np.zeros((len(tracks), 5), np.float32)
        for i, (m, p) in enumerate(tracks.items()):
            x, y, z = p[f] * 1000.0
            pts[i, :3] = (x, z, -y) if screen[1] == "+Y" else (x, y, z)
            if f in (unvisited or {}).get(m, []):
                pts[i, :4] = (0, 0, 0, -1)
        frames.append((pts, np.zeros((0, 0), np.float32)))
    writer.add_frames(frames)
    with open(path, "wb") as handle, warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="No analog data")  # point data only
        writer.write(handle)
    return path


@pytest.mark.parametrize("screen", [("+X", "+Y"), ("+X", "+Z")], ids=["y-up", "z-up"])
def test_c3d_points_read_in_metres_z_up(tmp_path, screen):
    pos = skeleton_motion(8, seed=2)
    c3d_file = write_c3d(tmp_path / "a.c3d", pos, POSE2SIM, screen=screen, unvisited={"LElbow": [3]})
    meta, heads, _ = read_keypoint_clip(c3d_file)
    index = {r: i for i, r in enumerate(meta["names"])}
    assert set(index) == set(POSE2SIM) and meta["frame_time"] == pytest.approx(1 / 30) and meta["frames"] == 8
    for role in POSE2SIM:
        keep = np.arange(8) != (3 if role == "l_elbow" else -1)
        assert np.abs(np.asarray(heads[keep, index[role]], np.float64) - pos[role][keep]).max() < 1e-4  # float32 mm
    e = np.asarray(heads[3, index["l_elbow"]], np.float64)
    assert np.abs(e - 0.5 * (pos["l_elbow"][2] + pos["l_elbow"][4])).max() < 1e-4  # the unseen point filled


@pytest.mark.parametrize("edit, message", [
    (lambda t: "hello\n" + t, r"line 1: not a TRC file"),
    (lambda t: t.replace("\tmm\t", "\tfurlong\t", 1), r"line 3: field Units: 'furlong' is not one of"),
    (lambda t: t.replace("30.0\t30.0", "0\t30.0", 1), r"line 3: field DataRate: expected a positive frame rate"),
    (lambda t: t.replace("\t17\tmm", "\t18\tmm", 1), r"line 4: 17 marker names, but field NumMarkers says 18"),
    (lambda t: t.replace("LKnee", "LeftThing", 1), r"no marker for l_knee \(markers: "),
    (lambda t: t.replace("LKnee", "LShoulder", 1), r"markers 'LShoulder' and 'LShoulder' have the same name"),
    (lambda t: re.sub(r"\n3\t([^\t]*)\t[^\t]*", r"\n3\t\1\tabc", t, count=1), r"line 9: 'abc' is not a number"),
])
def test_bad_files_are_one_line_errors(tmp_path, edit, message):
    trc = write_trc(tmp_path / "c.trc", skeleton_motion(4), POSE2SIM)
    trc.write_text(edit(trc.read_text()))
    with pytest.raises(KeypointClipError, match=f"^{trc}: {message}") as err:
        read_keypoint_clip(trc)
    assert "\n" not in str(err.value)


def test_screen_axes_turn_up_to_z_and_right_to_x():
    for x_screen, y_screen in (("+X", "+Y"), ("-Y", "+Z"), ("+Z", "-X"), ("-X", "-Y")):
        R = z_up_from_screen(x_screen, y_screen)
        up, right = (np.eye(3)["XYZ".index(a[1])] * (1 if a[0] == "+" else -1) for a in (y_screen, x_screen))
        assert np.allclose(R @ up, [0, 0, 1]) and np.allclose(R @ right, [1, 0, 0])
        assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)  # a rotation
    assert np.array_equal(z_up_from_screen("", ""), np.eye(3)) and np.array_equal(z_up_from_screen("+X", "+X"), np.eye(3))


def test_a_broken_c3d_file_is_one_line(tmp_path):
    bad = tmp_path / "bad.c3d"
    bad.write_bytes(b"\x02P" + bytes(100))
    with pytest.raises(KeypointClipError, match=f"^{bad}: not a readable C3D file") as err:
        read_keypoint_clip(bad)
    assert "\n" not in str(err.value)


def test_motions_import_reads_a_folder_of_trc_files(tmp_path):
    clips = tmp_path / "trc"
    clips.mkdir()
    write_trc(clips / "p1_balance.trc", skeleton_motion(10, seed=1), POSE2SIM, rate=60.0)
    broken = write_trc(clips / "p2_broken.trc", skeleton_motion(4), POSE2SIM)
    broken.write_text(broken.read_text().replace("\tmm\t", "\tfurlong\t", 1))
    env = {**os.environ, "SILPOSE_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-m", "silpose.shared.cli", "motions", "import", str(clips), "--library",
                        str(tmp_path / "lib"), "--subject", "auto", "--group", "balance", "-j", "1"],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    skipped = [ln for ln in r.stderr.splitlines() if ln.startswith("skipped: ")]
    assert len(skipped) == 1 and "p2_broken.trc: line 3: field Units" in skipped[0], r.stderr
    lib = load_library(tmp_path / "lib")
    assert [c["id"] for c in lib.clips] == ["p1_balance"] and lib.clips[0]["subject"] == "p1"
    assert lib.clips[0]["source_fps"] == 60.0 and lib.clips[0]["frames"] == 5  # 60 fps thinned to 30
