"""Drills: generation killed mid-shard (worker or driver, SIGKILL) and two runs into one folder.

Invariants: a rerun completes with data identical to an uninterrupted run; no partial or temporary
file is ever visible under a final shard name; two runs never interleave shards in one folder (the
second refuses with a clear error naming the lock and its holder).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from silpose.datagen.config import load_config
from silpose.datagen.executor import ExecutorError
from silpose.datagen.manifest import LOCK, MANIFEST
from silpose.datagen.pipeline import generate
from silpose.datagen.testing import DELAY_ENV, KILL_ENV, kill_process_group
from silpose.shared.dataset import SHARD_RE, DatasetError, load_split, read_metadata, read_shard

SYNTH = "silpose.datagen.testing:synthetic_render_samples"
KILLING = "silpose.datagen.testing:killing_render_samples"
SLOW = "silpose.datagen.testing:slow_render_samples"


class FinalNameWatcher(threading.Thread):
    """Polls a dataset folder while a run writes it: every file under a final shard name must be a
    complete, readable shard of ``rows`` rows (or have vanished between listing and reading)."""

    def __init__(self, folder, rows: int = 4):
        super().__init__(daemon=True)
        self.folder, self.rows = folder, rows
        self.stop = threading.Event()
        self.bad: list[str] = []
        self.checked = 0

    def run(self) -> None:
        while not self.stop.is_set():
            if self.folder.is_dir():
                for p in list(self.folder.iterdir()):
                    if not SHARD_RE.match(p.name):
                        continue
                    try:
                        n = len(read_shard(p))
                        self.checked += 1
                        if n != self.rows:
                            self.bad.append(f"{p.name}: {n} rows")
                    except DatasetError as exc:
                        if p.exists():
                            self.bad.append(str(exc))
            time.sleep(0.002)

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.join()


def hidden(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def assert_same_as_reference(out, reference) -> None:
    ref_root, ref_manifest = reference
    import json

    manifest = json.loads((out / MANIFEST).read_text())
    assert [(s["file"], s["sha256"]) for s in manifest["shards"]] == [(s["file"], s["sha256"]) for s in ref_manifest["shards"]]
    for split, n in (("train", 8), ("test", 4)):
        a, b = load_split(out, split, with_masks=True), load_split(ref_root, split, with_masks=True)
        np.testing.assert_array_equal(a.sample_id, np.arange(n))  # none missing, none twice
        for name in ("joints", "contours", "centroid", "scale", "masks", "touches_border"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert hidden(out) == []  # no lock, no temporaries


# ------------------------------------------------------------------ (a) a worker killed mid-shard


@pytest.mark.parametrize("workers", [1, 2])
def test_worker_sigkilled_mid_shard_then_rerun_equals_uninterrupted_run(clean_dataset, drill, tmp_path, monkeypatch, workers):
    marker = tmp_path / "killed-once"
    monkeypatch.setenv(KILL_ENV, f"train:6:{marker}")  # sample 6: the middle of shard train-00001
    cfg, out = drill.tiny_config(tmp_path), tmp_path / "ds"
    with FinalNameWatcher(out) as watch, pytest.raises(ExecutorError, match=r"died with exit code -9") as err:
        generate(cfg, out, workers=workers, render=KILLING, progress=False)
    assert marker.exists(), "the worker was not killed"
    assert "train-00001-of-00002.parquet" in str(err.value)
    assert watch.bad == []
    assert not (out / "train-00001-of-00002.parquet").exists() and not (out / MANIFEST).exists()
    assert hidden(out) == []  # the driver released its lock; the worker never writes files
    for p in out.glob("*.parquet"):  # whatever was finished is whole
        assert len(read_shard(p, with_masks=True)) == 4

    with FinalNameWatcher(out) as watch:
        manifest = generate(cfg, out, workers=workers, render=KILLING, progress=False)
    assert watch.bad == [] and watch.checked > 0
    assert manifest["timing"]["shards_rendered"] >= 1
    assert_same_as_reference(out, clean_dataset)


# ------------------------------------------------------------------ (a) the driver killed mid-write

_DYING_DRIVER = r"""
import os, signal, sys
from pathlib import Path
import pyarrow.parquet as pq

real_write_table, calls = pq.write_table, []

def dying_write_table(table, where, **kwargs):
    # The second shard: write it to its temporary name, cut it in half, die (SIGKILL) before the rename.
    real_write_table(table, where, **kwargs)
    calls.append(where)
    if len(calls) == 2:
        p = Path(where)
        p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
        print(p.name, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)

pq.write_table = dying_write_table

if __name__ == "__main__":
    from silpose.datagen.config import load_config
    from silpose.datagen.pipeline import generate
    generate(load_config(sys.argv[1]), sys.argv[2], workers=1, render=sys.argv[3], progress=False)
"""


def test_driver_sigkilled_while_writing_a_shard_then_rerun_equals_uninterrupted_run(clean_dataset, drill, tmp_path):
    cfg, out = drill.tiny_config(tmp_path), tmp_path / "ds"
    proc = subprocess.Popen([sys.executable, "-c", _DYING_DRIVER, str(tmp_path / "tiny.toml"), str(out), SYNTH],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        kill_process_group(proc.pid)  # the driver and any worker left
    assert proc.returncode == -signal.SIGKILL, stderr[-2000:]
    tmp_name = stdout.strip()
    assert tmp_name.startswith(".") and tmp_name.endswith(".tmp"), stdout
    final = [p.name for p in out.iterdir() if SHARD_RE.match(p.name)]
    assert len(final) == 1  # the first shard only; the half-written second one is not under its name
    assert len(read_shard(out / final[0], with_masks=True)) == 4
    assert (out / tmp_name).exists() and (out / LOCK).exists()  # a stale lock and a partial temporary
    assert not (out / MANIFEST).exists()

    manifest = generate(cfg, out, workers=1, render=SYNTH, progress=False)  # takes over the stale lock
    assert manifest["timing"]["shards_skipped"] == 1 and manifest["timing"]["shards_rendered"] == 2
    assert_same_as_reference(out, clean_dataset)


# ------------------------------------------------------------------ (d) two runs into one folder

_RUN = r"""
import sys
if __name__ == "__main__":
    from silpose.datagen.config import load_config
    from silpose.datagen.manifest import LockError
    from silpose.datagen.pipeline import GenerationError, generate
    try:
        generate(load_config(sys.argv[1]), sys.argv[2], workers=1, render=sys.argv[3], progress=False)
    except (LockError, GenerationError) as exc:
        print(f"refused: {exc}", flush=True)
        sys.exit(3)
    print("done", flush=True)
"""


def _start(cfg_path, out, env):
    return subprocess.Popen([sys.executable, "-c", _RUN, str(cfg_path), str(out), SLOW], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)


def _finish(proc):
    try:
        out, err = proc.communicate(timeout=180)
    finally:
        kill_process_group(proc.pid)  # the driver and any worker left
    return proc.returncode, out, err


def test_second_run_started_during_the_first_refuses_and_nothing_interleaves(clean_dataset, drill, tmp_path):
    a_dir, b_dir, out = tmp_path / "a", tmp_path / "b", tmp_path / "ds"
    a_dir.mkdir(), b_dir.mkdir()
    drill.tiny_config(a_dir)
    drill.tiny_config(b_dir, drill.TINY.replace("seed = 7", "seed = 8"))
    env = dict(os.environ, **{DELAY_ENV: "0.15"})
    first = _start(a_dir / "tiny.toml", out, env)
    deadline = time.monotonic() + 60
    while not (out / LOCK).exists():
        assert time.monotonic() < deadline and first.poll() is None, "first run never took the lock"
        time.sleep(0.01)
    second = _start(b_dir / "tiny.toml", out, env)
    code_b, out_b, err_b = _finish(second)
    still_running = first.poll() is None
    code_a, out_a, err_a = _finish(first)
    assert still_running, "the first run ended before the second was refused: the drill did not overlap"
    assert code_a == 0 and "done" in out_a, err_a[-2000:]
    assert code_b == 3, (out_b, err_b[-2000:])
    assert f"{out / LOCK}: another 'silpose gen' (pid {first.pid}" in out_b
    assert {read_metadata(p)["config"]["seed"] for p in out.glob("*.parquet")} == {7}
    assert_same_as_reference(out, clean_dataset)


def test_two_runs_started_together_one_wins_and_the_folder_is_the_winners(clean_dataset, drill, tmp_path):
    dirs = {7: tmp_path / "a", 8: tmp_path / "b"}
    for seed, d in dirs.items():
        d.mkdir()
        drill.tiny_config(d, drill.TINY.replace("seed = 7", f"seed = {seed}"))
    out = tmp_path / "ds"
    env = dict(os.environ, **{DELAY_ENV: "0.1"})
    procs = {seed: _start(d / "tiny.toml", out, env) for seed, d in dirs.items()}
    results = {seed: _finish(p) for seed, p in procs.items()}
    winners = [s for s, (code, _, _) in results.items() if code == 0]
    losers = [s for s, (code, _, _) in results.items() if code == 3]
    assert len(winners) == 1 and len(losers) == 1, results
    message = results[losers[0]][1]
    assert "another 'silpose gen'" in message or "field 'config' differs" in message, message
    assert {read_metadata(p)["config"]["seed"] for p in out.glob("*.parquet")} == set(winners)
    if winners == [7]:
        reference = clean_dataset
    else:
        reference = (tmp_path / "ref", generate(load_config(dirs[8] / "tiny.toml"), tmp_path / "ref", workers=1, render=SYNTH,
                                                 progress=False))
    assert_same_as_reference(out, reference)


# ------------------------------------------------------------------ resume over a damaged shard


@pytest.mark.parametrize("column", ["sample_id", "contours", "masks"])
def test_rerun_rewrites_a_complete_looking_but_damaged_shard(clean_dataset, drill, tmp_path, column):
    """A shard with an intact footer and right row count but a damaged data page is not "complete":
    the rerun renders it again instead of keeping it (and hashing the damage into the manifest)."""
    import pyarrow.parquet as pq

    cfg, out = drill.tiny_config(tmp_path), tmp_path / "ds"
    generate(cfg, out, workers=1, render=SYNTH, progress=False)
    path = out / "train-00001-of-00002.parquet"
    rg = pq.ParquetFile(path).metadata.row_group(0)
    chunk = next(rg.column(j) for j in range(rg.num_columns) if rg.column(j).path_in_schema.split(".")[0] == column)
    start = chunk.dictionary_page_offset if chunk.has_dictionary_page else chunk.data_page_offset
    data = bytearray(path.read_bytes())
    for i in range(start + chunk.total_compressed_size - 6, start + chunk.total_compressed_size - 2):
        data[i] ^= 0xA5  # the end of the chunk: compressed page data, not the page header
    path.write_bytes(bytes(data))
    (out / MANIFEST).unlink()
    manifest = generate(cfg, out, workers=1, render=SYNTH, progress=False)
    assert manifest["timing"]["shards_rendered"] == 1
    assert_same_as_reference(out, clean_dataset)


# ------------------------------------------------------------------ (d) the lock itself


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_a_live_holder_keeps_the_lock_whatever_its_file_says(tmp_path):
    """Two runs that both found a stale lock file must not both get the lock: after the first took
    it, the second still sees the dead run's record (it read the file before) -- reproduced here by
    writing that record over the live holder's file."""
    import json
    import socket

    from silpose.datagen.manifest import FolderLock, LockError

    first = FolderLock(tmp_path)
    first.acquire()
    (tmp_path / LOCK).write_text(json.dumps({"pid": _dead_pid(), "host": socket.gethostname(), "started": "then"}))
    with pytest.raises(LockError, match="another 'silpose gen'"):
        FolderLock(tmp_path).acquire()
    assert first.held
    first.release()
    assert not (tmp_path / LOCK).exists()
    with FolderLock(tmp_path):  # free again
        pass


def test_a_lock_file_naming_a_reused_pid_is_taken_over(tmp_path):
    """A run killed with SIGKILL leaves its lock file; if its pid now belongs to another live process,
    the folder must not stay locked forever."""
    import json
    import socket

    from silpose.datagen.manifest import FolderLock

    unrelated = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / LOCK).write_text(json.dumps({"pid": unrelated.pid, "host": socket.gethostname(), "started": "then"}))
        with FolderLock(tmp_path) as lock:
            assert lock.held and json.loads((tmp_path / LOCK).read_text())["pid"] == os.getpid()
    finally:
        unrelated.kill()
        unrelated.wait()
    assert not (tmp_path / LOCK).exists()
