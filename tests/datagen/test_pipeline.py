"""The sharded pipeline: resume, lock, failures, worker-count independence, third-party readers.

Fast tests use ``silpose.datagen.testing.synthetic_render_samples`` (a stick figure drawn with
OpenCV, clearly not a person) to exercise IO and orchestration; the ``blender`` tests use the
real renderer on a 12-sample config.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

from silpose.datagen.executor import ExecutorError
from silpose.datagen.manifest import LOCK, FolderLock, LockError, sha256_file
from silpose.datagen.pipeline import GenerationError, dataset_metadata, generate, plan_shards
from silpose.datagen.shards import shard_is_complete
from silpose.datagen.validate import validate_dataset
from silpose.datagen.testing import SYNTH_RENDER, synthetic_render_samples, tiny_config, tiny_config_toml
from silpose.shared.dataset import load_split, write_shard

SYNTH = SYNTH_RENDER
TINY = tiny_config_toml()


def leftovers(folder):
    """Temporary or partial files left in a dataset folder."""
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp") or p.name == LOCK)


def test_resume_rewrites_only_missing_or_broken_shards(tmp_path):
    cfg = tiny_config(tmp_path)
    out = tmp_path / "ds"
    first = generate(cfg, out, workers=1, render=SYNTH, progress=False)
    hashes = {s["file"]: s["sha256"] for s in first["shards"]}
    keep = out / "train-00000-of-00002.parquet"
    mtime = keep.stat().st_mtime_ns
    (out / "train-00001-of-00002.parquet").unlink()
    broken = out / "test-00000-of-00001.parquet"
    broken.write_bytes(broken.read_bytes()[:100])
    stale = out / ".train-00001-of-00002.parquet.99999.tmp"
    stale.write_bytes(b"partial")
    second = generate(cfg, out, workers=1, render=SYNTH, progress=False)
    assert second["timing"]["shards_rendered"] == 2 and second["timing"]["shards_skipped"] == 1
    assert keep.stat().st_mtime_ns == mtime
    assert {s["file"]: s["sha256"] for s in second["shards"]} == hashes
    assert leftovers(out) == []
    ids = load_split(out, "train").sample_id
    np.testing.assert_array_equal(ids, np.arange(8))


def test_second_run_refuses_while_the_folder_is_locked(tmp_path):
    cfg = tiny_config(tmp_path)
    out = tmp_path / "ds"
    out.mkdir()
    with FolderLock(out):
        with pytest.raises(LockError, match=rf"{LOCK}: another 'silpose gen' \(pid {os.getpid()}"):
            generate(cfg, out, workers=1, render=SYNTH, progress=False)
    assert not list(out.glob("*.parquet"))


def test_stale_lock_of_a_dead_process_is_taken_over(tmp_path):
    cfg = tiny_config(tmp_path)
    out = tmp_path / "ds"
    out.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (out / LOCK).write_text(json.dumps({"pid": dead.pid, "host": socket.gethostname(), "started": "then"}))
    generate(cfg, out, workers=1, render=SYNTH, progress=False)
    assert leftovers(out) == [] and len(list(out.glob("*.parquet"))) == 3


def test_a_folder_of_another_config_is_refused(tmp_path):
    out = tmp_path / "ds"
    generate(tiny_config(tmp_path), out, workers=1, render=SYNTH, progress=False)
    other_seed = tiny_config(tmp_path, TINY.replace("seed = 7", "seed = 8"))
    with pytest.raises(GenerationError, match="field 'config' differs from this run's"):
        generate(other_seed, out, workers=1, render=SYNTH, progress=False)
    other_shards = tiny_config(tmp_path, TINY.replace("shard_size = 4", "shard_size = 3"))
    with pytest.raises(GenerationError, match="shard of another configuration"):
        generate(other_shards, out, workers=1, render=SYNTH, progress=False)
    assert leftovers(out) == []


def test_a_resume_with_another_max_redraws_keeps_the_finished_shards(tmp_path):
    """A failed run (a sample beyond max_redraws) resumed with a larger max_redraws keeps its finished shards
    (their samples cannot change: shards.RESUME_NEUTRAL), restamped so every shard holds the new config."""
    out = tmp_path / "ds"
    out.mkdir()
    first = tiny_config(tmp_path)  # max_redraws = 50; its train shards finished, its test shard failed:
    for task in plan_shards(first)[:2]:  # written here as the run writes them, without spawning workers
        write_shard(out / task.file, synthetic_render_samples(first.worker_config(), task.split, list(task.indices)),
                    dataset_metadata(first))
    kept = {p.name: pq.read_table(p).to_pydict() for p in sorted(out.glob("train-*.parquet"))}
    assert len(kept) == 2
    more = tiny_config(tmp_path, TINY.replace("max_redraws = 50", "max_redraws = 1000"))
    manifest = generate(more, out, workers=1, render=SYNTH, progress=False)  # refused before: "differs"
    assert manifest["timing"]["shards_skipped"] == 2 and manifest["timing"]["shards_rendered"] == 1
    assert {p.name: pq.read_table(p).to_pydict() for p in sorted(out.glob("train-*.parquet"))} == kept
    split = load_split(out, "train")  # the readers demand one config in every shard
    assert split.metadata["config"]["max_redraws"] == 1000 and manifest["config"]["max_redraws"] == 1000
    # lowered below a kept sample's redraws: that shard is not kept (this run would have failed the sample)
    fewer = dataset_metadata(tiny_config(tmp_path, TINY.replace("max_redraws = 50", "max_redraws = 0")))
    verdicts = []
    for task in plan_shards(more):
        redrawn = bool(np.any(pq.read_table(out / task.file, columns=["redraws"]).column("redraws").to_numpy() > 0))
        verdicts.append(redrawn)
        assert shard_is_complete(out / task.file, task, fewer) is not redrawn
    assert any(verdicts)  # the stand-in redraws some samples once


def test_a_resume_with_another_train_table_keeps_the_shards(tmp_path):
    """``[train]`` (``silpose train``'s defaults) is read after generation: a rerun that adds it keeps every shard
    (shards.RESUME_NEUTRAL) and restamps them, so the trainer finds it in the split's config."""
    out = tmp_path / "ds"
    generate(tiny_config(tmp_path), out, workers=1, render=SYNTH, progress=False)
    kept = {p.name: pq.read_table(p).to_pydict() for p in sorted(out.glob("*.parquet"))}
    trained = tiny_config(tmp_path, TINY + "[train]\nfits = 3\nlatent = 2\n")
    manifest = generate(trained, out, workers=1, render=SYNTH, progress=False)
    assert manifest["timing"]["shards_rendered"] == 0 and manifest["config"]["train"] == {"fits": 3, "latent": 2}
    assert {p.name: pq.read_table(p).to_pydict() for p in sorted(out.glob("*.parquet"))} == kept
    assert load_split(out, "train").metadata["config"]["train"] == {"fits": 3, "latent": 2}
    # the restamped shards are the files a fresh generation of that config writes, byte for byte
    fresh = generate(trained, tmp_path / "fresh", workers=1, render=SYNTH, progress=False)
    assert fresh["timing"]["shards_rendered"] == len(kept)
    for shard in sorted(out.glob("*.parquet")):
        assert shard.read_bytes() == (tmp_path / "fresh" / shard.name).read_bytes(), shard.name
    assert [s["sha256"] for s in manifest["shards"]] == [s["sha256"] for s in fresh["shards"]]


def test_a_dataset_made_before_an_augmentation_field_existed_resumes_with_it_off(tmp_path):
    """``[motion] part_mix`` / ``limb_swing`` at 0 draw and render what a config without them does
    (shards.MOTION_DEFAULTS): the motions preset's 48,000 samples, made before ``part_mix`` existed, were refused
    ("field 'config' differs") by every later `silpose gen motions`. Any other value is another dataset."""
    import copy

    config = tiny_config(tmp_path)
    task = plan_shards(config)[0]
    before = dataset_metadata(config)
    before["config"]["motion"] = {"source": "library", "mirror": True}  # as written before the fields existed
    write_shard(tmp_path / task.file, synthetic_render_samples(config.worker_config(), task.split, list(task.indices)),
                before)
    now = copy.deepcopy(before)
    now["config"]["motion"].update(part_mix=0.0, limb_swing=0.0)
    assert shard_is_complete(tmp_path / task.file, task, now)
    for field, value in (("part_mix", 0.3), ("limb_swing", 0.5)):
        other = copy.deepcopy(now)
        other["config"]["motion"][field] = value
        with pytest.raises(GenerationError, match="differs"):
            shard_is_complete(tmp_path / task.file, task, other)


def test_worker_failure_names_the_shard_and_leaves_no_partial_file(tmp_path):
    out = tmp_path / "ds"
    with pytest.raises(ExecutorError, match=r"shard test-00000-of-00001.parquet: worker failed: RuntimeError: synthetic"):
        generate(tiny_config(tmp_path), out, workers=1, render="silpose.datagen.testing:failing_render_samples",
                 progress=False)
    assert leftovers(out) == []
    assert not (out / "test-00000-of-00001.parquet").exists()
    for p in out.glob("train-*.parquet"):  # completed shards are whole and will be kept by a rerun
        assert pq.ParquetFile(p).metadata.num_rows == 4


def test_renderer_returning_wrong_ids_is_caught(tmp_path):
    with pytest.raises(GenerationError, match="field 'sample_id'"):
        generate(tiny_config(tmp_path), tmp_path / "ds", workers=1,
                 render="silpose.datagen.testing:wrong_ids_render_samples", progress=False)
    assert not list((tmp_path / "ds").glob("*.parquet"))


def test_unusable_output_folder(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(GenerationError, match="cannot create the output folder") as err:
        generate(tiny_config(tmp_path), blocker / "ds", workers=1, render=SYNTH, progress=False)
    assert str(blocker / "ds") in str(err.value)


def test_synthetic_data_do_not_depend_on_worker_count(tmp_path):
    cfg = tiny_config(tmp_path)
    a = generate(cfg, tmp_path / "a", workers=1, render=SYNTH, progress=False)
    b = generate(cfg, tmp_path / "b", workers=2, render=SYNTH, progress=False)
    assert [s["sha256"] for s in a["shards"]] == [s["sha256"] for s in b["shards"]]


# ----------------------------------------------------------------------------- real renderer


@pytest.fixture(scope="module")
def real_one_worker(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("real1")
    cfg = tiny_config(tmp)
    manifest = generate(cfg, tmp / "ds", workers=1, progress=False)
    return tmp / "ds", manifest


@pytest.mark.blender
def test_real_renderer_identical_with_one_and_two_workers(real_one_worker, tmp_path):
    out1, m1 = real_one_worker
    m2 = generate(tiny_config(tmp_path), tmp_path / "ds2", workers=2, progress=False)
    assert "bpy" not in sys.modules  # the driver never imports Blender
    for split in ("train", "test"):
        a = load_split(out1, split, with_masks=True)
        b = load_split(tmp_path / "ds2", split, with_masks=True)
        for name in ("sample_id", "joints", "contours", "centroid", "scale", "masks", "touches_border"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        for key in a.gait:
            np.testing.assert_array_equal(a.gait[key], b.gait[key])
    assert [s["sha256"] for s in m1["shards"]] == [s["sha256"] for s in m2["shards"]]
    assert m2["timing"]["workers"] == 2 and len(m2["timing"]["worker_rss_mb"]) == 2


@pytest.mark.blender
def test_real_dataset_validates(real_one_worker):
    out, manifest = real_one_worker
    report = validate_dataset(out)
    assert report.ok, report.format()
    assert report.splits["train"]["joints_inside"] >= 0.99
    assert manifest["counts"] == {"train": 8, "test": 4}
    for s in manifest["shards"]:
        assert sha256_file(out / s["file"]) == s["sha256"]


@pytest.mark.blender
def test_third_party_readers(real_one_worker):
    """pyarrow, DuckDB and Polars read the shards back without silpose code."""
    import duckdb
    import polars as pl
    import pyarrow.dataset as ds

    out, _ = real_one_worker
    ref = load_split(out, "train")
    table = ds.dataset(sorted(out.glob("*.parquet")), format="parquet").to_table()
    assert table.num_rows == 12
    train = table.filter(ds.field("split") == "train")
    joints = train.column("joints").combine_chunks().flatten().flatten().to_numpy().reshape(-1, 19, 3)
    np.testing.assert_array_equal(joints, ref.joints)

    con = duckdb.connect()
    glob = str(out / "*.parquet")
    counts = dict(con.sql(f"SELECT split, count(*) FROM read_parquet('{glob}') GROUP BY split").fetchall())
    assert counts == {"train": 8, "test": 4}
    rows = con.sql(
        f"SELECT contour_scale, joints, gait.phase FROM read_parquet('{out}/train-*.parquet') ORDER BY sample_id"
    ).fetchall()
    np.testing.assert_array_equal(np.array([r[0] for r in rows], np.float32), ref.scale)
    np.testing.assert_array_equal(np.array([r[1] for r in rows], np.float32).reshape(8, 19, 3), ref.joints)
    np.testing.assert_array_equal(np.array([r[2] for r in rows], np.float32), ref.gait["phase"])

    df = pl.read_parquet(str(out / "train-*.parquet"), columns=["sample_id", "contours"]).sort("sample_id")
    assert df.height == 8
    contours = np.array(df["contours"].to_list(), dtype=np.float32).reshape(8, 4, 200, 2)
    np.testing.assert_array_equal(contours, ref.contours)


def test_a_dying_worker_is_reported_not_waited_for(tmp_path):
    """multiprocessing.Pool loses the task of a dead worker; the driver must notice, not hang."""
    out = tmp_path / "ds"
    with pytest.raises(ExecutorError, match=r"worker process \d+ died with exit code 3 .*test-00000-of-00001"):
        generate(tiny_config(tmp_path), out, workers=1, render="silpose.datagen.testing:crashing_render_samples",
                 progress=False)
    assert leftovers(out) == [] and not (out / "test-00000-of-00001.parquet").exists()


def test_preparing_a_folder_another_run_probes_at_the_same_moment_is_not_refused(tmp_path, monkeypatch):
    """Two runs started together both probe the folder with the same file: when the other run removes it between
    this one's write and removal, the folder is still writable (the drill that starts two runs at once had seen
    'output folder is not writable (No such file or directory)')."""
    from pathlib import Path

    from silpose.datagen.shards import prepare_folder

    real_write = Path.write_bytes

    def write_then_the_other_run_removes_it(self, data):
        n = real_write(self, data)
        if self.name == ".silpose-write-probe":
            os.unlink(self)
        return n

    monkeypatch.setattr(Path, "write_bytes", write_then_the_other_run_removes_it)
    prepare_folder(tmp_path / "ds")
    assert (tmp_path / "ds").is_dir() and not any((tmp_path / "ds").iterdir())
    monkeypatch.undo()
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro").chmod(0o500)
    try:
        if os.access(tmp_path / "ro", os.W_OK):  # root writes anywhere: nothing to check
            return
        with pytest.raises(GenerationError, match="not writable"):
            prepare_folder(tmp_path / "ro")
    finally:
        (tmp_path / "ro").chmod(0o700)
