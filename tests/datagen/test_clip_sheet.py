"""``silpose motions show``: a library clip drawn as stick figures (:mod:`silpose.datagen.motion.clip_sheet`)."""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest

from silpose.datagen.motion.clip_sheet import find_clip, sheet_poses
from silpose.datagen.motion.library import ROLES, load_library


def test_each_drawn_frame_is_the_clips_pose_moved_rigidly_onto_the_floor_facing_the_viewer():
    lib = load_library(None)
    c = find_clip(lib, "cmu_05_12")
    frames, poses = sheet_poses(lib, c, 6)
    P = lib.positions(c)
    rows = lib.rows(c)
    assert len(frames) == len(poses) == 6 and frames[0] == lib.frame[rows][0] and frames[-1] == lib.frame[rows][-1]
    where = {int(f): k for k, f in enumerate(lib.frame[rows])}
    L, R = ROLES.index("l_hip"), ROLES.index("r_hip")
    feet = [ROLES.index(r) for r in ("l_ankle", "r_ankle", "l_toe", "r_toe")]
    for f, q in zip(frames, poses):
        p = P[where[int(f)]]
        dist = lambda x: np.linalg.norm(x[:, None] - x[None], axis=2)  # noqa: E731
        assert np.allclose(dist(q), dist(p), atol=1e-9)  # a rigid move
        assert np.allclose(np.diff(q[:, 2]), np.diff(p[:, 2]), atol=1e-9)  # turned about the vertical only
        assert abs(q[L, 1] - q[R, 1]) < 1e-9 and q[L, 0] > q[R, 0]  # hip line along +x
        assert np.allclose(q[0, :2], 0.0, atol=1e-9) and q[feet, 2].min() == pytest.approx(0.0, abs=1e-12)


def test_the_command_writes_a_picture_and_names_a_clip_it_lacks(tmp_path):
    out = tmp_path / "clip.png"
    cmd = [sys.executable, "-m", "silpose.shared.cli", "motions", "show"]
    r = subprocess.run(cmd + ["cmu_05_12", "-n", "5", "-o", str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    img = cv2.imread(str(out))
    assert img is not None and img.shape[1] > img.shape[0] > 200
    r = subprocess.run(cmd + ["cmu_05_99", "-o", str(tmp_path / "x.png")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "no clip 'cmu_05_99'" in r.stderr and "cmu_05_" in r.stderr
    r = subprocess.run(cmd + ["cmu_05_12", "-o", str(tmp_path / "x.jpg")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "--out must be a .png file" in r.stderr
