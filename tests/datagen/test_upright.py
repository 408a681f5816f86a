"""Clips written with another up axis than their format says (a Z-up BVH): turned to stand.

Reference: the same motion written Y up (``silpose.datagen.testing.write_synthetic_bvh``), both
imported by Blender's own BVH importer."""

from __future__ import annotations

import numpy as np
import pytest

from silpose.datagen.motion.build import ClipSource, import_clips
from silpose.datagen.motion.clips import ensure_cached, read_entry
from silpose.datagen.motion.joint_maps import UPRIGHT, resolve_map, upright_turn
from silpose.datagen.motion.library import load_library, role_positions
from silpose.datagen.testing import write_synthetic_bvh


@pytest.mark.parametrize("axis", ["+x", "-x", "+y", "-y", "-z"])
def test_the_turn_takes_the_spines_axis_to_up_by_the_smallest_rotation(axis):
    rng = np.random.default_rng(3)
    a = np.zeros(3)
    a["xyz".index(axis[1])] = 1.0 if axis[0] == "+" else -1.0
    spine = a + rng.normal(0, 0.2, 3)  # leaning up to ~20 degrees off the axis
    R, name = upright_turn(spine)
    R = np.asarray(R)
    assert name == axis
    assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
    assert np.allclose(R @ a, [0, 0, 1])
    angle = np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
    assert angle == pytest.approx(180.0 if axis == "-z" else 90.0)


def test_a_rest_pose_within_45_degrees_of_up_is_not_turned():
    for spine in ([0, 0, 1], [0.9, 0, 1.0], [0, -0.99, 1.0]):
        assert upright_turn(np.array(spine, float)) == (UPRIGHT, "+z")
    assert upright_turn(np.array([0, -1.01, 1.0]))[1] == "-y"


@pytest.mark.blender
def test_a_z_up_bvh_gives_the_y_up_files_poses(tmp_path, monkeypatch):
    monkeypatch.setenv("SILPOSE_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "y").mkdir()
    (tmp_path / "z").mkdir()
    y_up = write_synthetic_bvh(tmp_path / "y" / "walk.bvh", n_frames=5)
    z_up = write_synthetic_bvh(tmp_path / "z" / "walk.bvh", n_frames=5, up="z")
    entries = ensure_cached([y_up, z_up], tmp_path / "cache" / "bvh", workers=2)
    got = {}
    for path in (y_up, z_up):
        arr = read_entry(entries[path][1])
        m = arr.meta
        jmap = resolve_map(m["names"], m["parents"], m["rest_heads"], m["rest_tails"], "auto", str(path))
        got[path] = (jmap, role_positions(np.asarray(arr.heads, float), np.asarray(arr.tails, float), jmap), arr)
    (jy, py, ay), (jz, pz, az) = got[y_up], got[z_up]
    assert jy.rest_up == "+z" and jz.rest_up == "-y"
    assert np.abs(np.asarray(az.heads)[:, :, 2] - np.asarray(ay.heads)[:, :, 2]).max() > 0.3  # lying as read
    assert np.nanmax(np.abs(pz - py)) < 1e-5  # standing once turned
    report = import_clips([ClipSource(path=y_up, id="y", subject="1"), ClipSource(path=z_up, id="z", subject="1")],
                          tmp_path / "lib", fps=30.0, workers=1, cache=tmp_path / "cache" / "bvh")
    assert report.added == ["y", "z"]
    lib = load_library(tmp_path / "lib")
    rows = {c["id"]: lib.rows(i) for i, c in enumerate(lib.clips)}
    assert np.allclose(lib.dirs[rows["y"]], lib.dirs[rows["z"]], atol=1e-5)
    assert lib.clips[1]["rest_up"] == "-y" and "rest_up" not in lib.clips[0]
    assert lib.clips[0]["extent_m"] == pytest.approx(lib.clips[1]["extent_m"], abs=1e-4)
