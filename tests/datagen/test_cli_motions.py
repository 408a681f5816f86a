"""``silpose motions import`` and ``silpose motions list`` as a user runs them, bad files included.

The import runs Blender's importer in spawned workers (a few seconds per clip); this process never
imports bpy.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq

from silpose.datagen.motion.library import CMU_ACKNOWLEDGEMENT, FRAMES_NAME, MANIFEST_NAME
from silpose.datagen.testing import write_synthetic_bvh


def silpose(*args, cwd=None, env=None, timeout=900):
    return subprocess.run([sys.executable, "-m", "silpose.shared.cli", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, env=env, timeout=timeout)


def test_list_shows_the_bundled_library_by_group_with_licence_and_acknowledgement():
    r = silpose("motions", "list")
    assert r.returncode == 0, r.stderr
    out = r.stdout
    for group in ("walk", "dance", "sports", "balance"):
        assert f"\n{group}: " in out
    assert "cmu_05_12" in out and "free for research and commercial use" in out
    assert CMU_ACKNOWLEDGEMENT in out
    r = silpose("motions", "list", "--library", "/nonexistent/lib")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "/nonexistent/lib" in r.stderr


def test_import_skips_bad_files_one_line_each_and_extends(tmp_path, monkeypatch):
    clips = tmp_path / "clips"
    clips.mkdir()
    good = write_synthetic_bvh(clips / "good.bvh", n_frames=6)
    text = good.read_text()
    lines = text.splitlines()
    (clips / "truncated.bvh").write_text("\n".join(lines[:-2]) + "\n")
    (clips / "empty_motion.bvh").write_text(text.split("MOTION")[0] + "MOTION\nFrames: 0\nFrame Time: 0.033333\n")
    (clips / "alien.bvh").write_text(text.replace("LeftLeg", "BoneA").replace("RightLeg", "BoneB"))  # no knees
    # names no built-in map knows, read off the skeleton (silpose.datagen.motion.name_match): same motion as good
    (clips / "thighs.bvh").write_text(text.replace("LeftUpLeg", "ThighL").replace("RightUpLeg", "ThighR"))
    lib = tmp_path / "lib"
    env = {**__import__("os").environ, "SILPOSE_CACHE_DIR": str(tmp_path / "cache")}
    r = silpose("motions", "import", clips, "--library", lib, "--group", "test-group", "--first", "1", "-j", "1", env=env)
    assert r.returncode == 0, r.stderr
    skipped = [ln for ln in r.stderr.splitlines() if ln.startswith("skipped: ")]
    assert len(skipped) == 3, r.stderr
    for name in ("truncated.bvh", "empty_motion.bvh", "alien.bvh"):
        assert sum(name in ln for ln in skipped) == 1, (name, skipped)
    assert "2 clips imported, 3 skipped" in r.stdout
    assert sorted(p.name for p in lib.iterdir()) == [FRAMES_NAME, MANIFEST_NAME]
    m = json.loads((lib / MANIFEST_NAME).read_text())
    assert [c["id"] for c in m["clips"]] == ["good", "thighs"] and {c["group"] for c in m["clips"]} == {"test-group"}
    assert m["clips"][0]["frames"] == m["clips"][1]["frames"] == 5  # frames 1..5 of 6 at the synthetic clip's rate
    table = pq.read_table(lib / FRAMES_NAME)
    dirs = np.asarray(table.column("dirs").combine_chunks().flatten().to_numpy()).reshape(10, -1, 3)
    assert np.allclose(np.linalg.norm(dirs[np.isfinite(dirs[..., 0])], axis=1), 1, atol=1e-5)
    np.testing.assert_allclose(dirs[5:], dirs[:5], atol=1e-6)  # the renamed skeleton gives the same bone directions
    # extend: another copy under a new name is added, the first kept
    (tmp_path / "more").mkdir()
    (tmp_path / "more" / "again.bvh").write_text(text)
    r = silpose("motions", "import", tmp_path / "more", "--library", lib, "-j", "1", env=env)
    assert r.returncode == 0 and "1 clips imported, 0 skipped, 2 kept" in r.stdout, r.stdout + r.stderr
    r = silpose("motions", "list", "--library", lib)
    assert "test-group: 2 clips" in r.stdout and "other: 1 clips" in r.stdout
    # never into a folder holding someone else's files
    (tmp_path / "foreign").mkdir()
    (tmp_path / "foreign" / "notes.txt").write_text("mine")
    r = silpose("motions", "import", clips / "good.bvh", "--library", tmp_path / "foreign", env=env)
    assert r.returncode == 2 and "did not write" in r.stderr and r.stderr.count("\n") == 1
    assert sorted(p.name for p in (tmp_path / "foreign").iterdir()) == ["notes.txt"]
