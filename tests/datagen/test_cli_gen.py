"""``silpose gen / validate / preview`` as a user runs them: bad input, SIGKILL and resume."""

from __future__ import annotations

from pathlib import Path

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from silpose.datagen.config import load_config
from silpose.datagen.pipeline import generate
from silpose.shared.camera import ring_rig
from silpose.shared.dataset import load_split
from silpose.shared.output_dir import MARKER

TINY = """name = "tiny"
seed = 5
renderer = "raster"
shard_size = 2
n_points = 200
max_redraws = 50
[splits]
train = 8
test = 4
"""


def silpose(*args, cwd=None, timeout=600):
    return subprocess.run([sys.executable, "-m", "silpose.shared.cli", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, timeout=timeout)


def error_line(result, command):
    lines = [l for l in result.stderr.splitlines() if l.startswith(f"silpose {command}: error: ")]
    assert len(lines) == 1, result.stderr
    return lines[0]


def no_partial_files(folder):
    if not folder.exists():
        return True
    return not [p for p in folder.rglob("*") if ".parquet" in p.name]


def test_unknown_preset(tmp_path):
    r = silpose("gen", "nope", "--out", tmp_path / "ds")
    assert r.returncode != 0
    presets = ", ".join(sorted(p.stem for p in (Path(__file__).resolve().parents[2] / "configs").glob("*.toml")))
    assert error_line(r, "gen") == f"silpose gen: error: nope: unknown preset; available presets: {presets}"
    assert no_partial_files(tmp_path / "ds")


def test_invalid_config_value(tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(TINY.replace("shard_size = 2", "shard_size = 0"))
    r = silpose("gen", cfg, "--out", tmp_path / "ds")
    assert r.returncode != 0
    line = error_line(r, "gen")
    assert str(cfg) in line and "'shard_size'" in line
    assert no_partial_files(tmp_path / "ds")


def test_rig_that_does_not_see_the_workspace(tmp_path):
    rig = tmp_path / "tele.json"
    rig.write_text(ring_rig(focal_px=1500.0).to_json())
    r = silpose("gen", "smoke", "--rig", rig, "--out", tmp_path / "ds")
    assert r.returncode != 0
    line = error_line(r, "gen")
    # blamed on the rig file, not on the preset's [rig] field; the camera, the corner, what silpose assumes
    assert line.startswith(f"silpose gen: error: {rig}: camera 'cam0' does not see the workspace corner"), line
    assert "field 'rig'" not in line and "z up" in line and "silpose rig show" in line
    assert no_partial_files(tmp_path / "ds")


@pytest.mark.parametrize("where", ["under_a_file", "proc"])
def test_unwritable_output_folder(tmp_path, where):
    if where == "under_a_file":
        (tmp_path / "file").write_text("x")
        out = tmp_path / "file" / "ds"
    else:
        out = "/proc/silpose-test-output"
    r = silpose("gen", "smoke", "--out", out)
    assert r.returncode != 0
    line = error_line(r, "gen")
    assert str(out) in line and ("cannot create the output folder" in line or "not writable" in line)
    assert no_partial_files(tmp_path)


def test_validate_truncated_and_foreign_parquet(tmp_path):
    from silpose.datagen.testing import synthetic_render_samples
    from silpose.shared.dataset import write_shard

    from silpose.datagen.pipeline import dataset_metadata

    cfg_path = tmp_path / "tiny.toml"
    cfg_path.write_text(TINY)
    cfg = load_config(cfg_path)
    good = tmp_path / "trunc" / "train-00000-of-00001.parquet"
    good.parent.mkdir()
    write_shard(good, synthetic_render_samples(cfg.worker_config(), "train", [0, 1]), dataset_metadata(cfg))
    good.write_bytes(good.read_bytes()[:-200])
    for target in (good, good.parent):
        r = silpose("validate", target)
        assert r.returncode == 1
        text = r.stdout + r.stderr
        assert str(good) in text and "not a readable Parquet file" in text

    foreign = tmp_path / "foreign" / "train-00000-of-00001.parquet"
    foreign.parent.mkdir()
    pq.write_table(pa.table({"a": [1.0, 2.0]}), foreign)
    r = silpose("validate", foreign)
    assert r.returncode == 1
    line = error_line(r, "validate")
    assert str(foreign) in line and "'silpose'" in line
    r = silpose("validate", foreign.parent)
    assert r.returncode == 1 and str(foreign) in r.stdout and "FAILED" in r.stdout


@pytest.mark.blender
def test_sigkill_then_resume_equals_an_uninterrupted_run(tmp_path):
    cfg_path = tmp_path / "tiny.toml"
    cfg_path.write_text(TINY)
    out = tmp_path / "killed"
    proc = subprocess.Popen(
        [sys.executable, "-m", "silpose.shared.cli", "gen", str(cfg_path), "--out", str(out), "--workers", "1",
         "--no-progress"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )
    deadline = time.monotonic() + 300
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if out.is_dir() and list(out.glob("*-of-*.parquet")):
                break
            time.sleep(0.02)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the driver and its workers, as a hard kill would
        proc.wait()
    done_before = sorted(p.name for p in out.glob("*-of-*.parquet"))
    assert 1 <= len(done_before) < 6, done_before  # killed mid-way
    assert not (out / "manifest.json").exists()

    r = silpose("gen", cfg_path, "--out", out, "--workers", "1", "--no-progress")
    assert r.returncode == 0, r.stderr[-2000:]
    assert f"{len(done_before)} already complete" in r.stdout
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == [MARKER]  # no lock, no temporaries

    reference = tmp_path / "reference"
    ref_manifest = generate(load_config(cfg_path), reference, workers=1, progress=False)
    import json

    resumed = json.loads((out / "manifest.json").read_text())
    assert [s["sha256"] for s in resumed["shards"]] == [s["sha256"] for s in ref_manifest["shards"]]
    for split, n in (("train", 8), ("test", 4)):
        a = load_split(out, split, with_masks=True)
        b = load_split(reference, split, with_masks=True)
        np.testing.assert_array_equal(a.sample_id, np.arange(n))  # no duplicate, none missing
        for name in ("joints", "contours", "masks"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))

    r = silpose("validate", out)
    assert r.returncode == 0, r.stdout
    assert "height px" in r.stdout and "contour length px" in r.stdout and "area px" in r.stdout
    assert (out / "README.md").is_file() and (out / "preview.png").is_file()
    assert "![" in (out / "README.md").read_text()


def test_driver_modules_never_import_blender():
    """Importing every datagen module (renderers and Blender adapters included) loads no bpy."""
    code = (
        "import importlib, pkgutil, sys\n"
        "import silpose.datagen\n"
        "names = [m.name for m in pkgutil.walk_packages(silpose.datagen.__path__, 'silpose.datagen.')]\n"
        "for name in names:\n"
        "    importlib.import_module(name)\n"
        "assert {'silpose.datagen.blender.scene', 'silpose.datagen.renderers', 'silpose.datagen.frames.render'} <= set(names)\n"
        "assert 'bpy' not in sys.modules, 'bpy imported'\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    r = silpose("gen", "--help")
    assert r.returncode == 0 and "--executor" in r.stdout and "--workers" in r.stdout
