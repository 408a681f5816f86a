"""The local executor: results equal in-process rendering, workers are recycled, and a worker killed
from outside (busy or idle) is reported at once, never waited for, with no process left behind.

The old ``multiprocessing.Pool`` executor hung once in CI after a worker was SIGKILLed (its
``terminate()`` can block on a queue lock; CPython issues 73945, 78178, 96995); these drills run the
executor in a child process under a timeout so a hang fails the test instead of the whole suite.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import psutil
import pytest

from silpose.datagen.executor import ExecutorError, ShardTask, WorkerDied, run_local, spawned_map
from silpose.datagen.testing import DELAY_ENV, STARTED_ENV, synthetic_render_samples, tiny_config, kill_process_group

SYNTH = "silpose.datagen.testing:synthetic_render_samples"


@pytest.fixture
def config(tmp_path) -> dict:
    """What the pipeline hands every task (a tiny raster config's ``worker_config``)."""
    return tiny_config(tmp_path).worker_config()


def workers_alive() -> list:
    """This process's children other than multiprocessing's resource tracker (it outlives pools)."""
    return [p for p in psutil.Process().children(recursive=True)
            if not any("resource_tracker" in part for part in p.cmdline())]


def tasks(n: int, size: int = 2) -> list[ShardTask]:
    return [ShardTask("train", k, n, tuple(range(k * size, (k + 1) * size)), f"train-{k:05d}-of-{n:05d}.parquet")
            for k in range(n)]


def test_results_equal_in_process_rendering_and_workers_are_recycled(config):
    jobs = tasks(5)
    out = dict(run_local(jobs, config, SYNTH, workers=2, max_tasks_per_child=1))
    assert sorted(t.shard for t in out) == list(range(5))
    for task, result in out.items():
        expected = synthetic_render_samples(config, task.split, list(task.indices))
        assert len(result["records"]) == len(expected)
        for got, want in zip(result["records"], expected):
            np.testing.assert_array_equal(got["contours"], want["contours"])
            np.testing.assert_array_equal(got["joints"], want["joints"])
    # one task per process: five tasks ran in five different processes, none of them this one
    pids = {r["pid"] for r in out.values()}
    assert len(pids) == 5 and os.getpid() not in pids
    assert workers_alive() == []  # all reaped


def test_a_longer_lived_worker_runs_several_tasks(config):
    out = dict(run_local(tasks(4), config, SYNTH, workers=1, max_tasks_per_child=20))
    assert len({r["pid"] for r in out.values()}) == 1


_DRIVER = r"""
import sys
from silpose.datagen.executor import ExecutorError, ShardTask, WorkerDied, run_local, spawned_map
from silpose.datagen.testing import tiny_config
config = tiny_config(sys.argv[2]).worker_config()
tasks = [ShardTask("train", k, 4, (2 * k, 2 * k + 1), f"train-{k:05d}-of-00004.parquet") for k in range(4)]
try:
    for task, result in run_local(tasks, config, sys.argv[1], workers=2):
        print("done", task.file, flush=True)
except ExecutorError as exc:
    print("error", exc, flush=True)
    sys.exit(3)
"""


def worker_processes(pid: int) -> list:
    return [p for p in psutil.Process(pid).children() if not any("resource_tracker" in c for c in p.cmdline())]


@pytest.mark.parametrize("victim", ["starting", "busy"])
def test_a_worker_killed_from_outside_is_reported_and_nothing_is_left_running(tmp_path, victim):
    """SIGKILL (the OOM killer) hits a worker still starting up, or one inside the renderer."""
    started = tmp_path / "started"
    started.mkdir()
    env = {**os.environ, DELAY_ENV: "2", STARTED_ENV: str(started)}  # 4 s per shard
    proc = subprocess.Popen([sys.executable, "-c", _DRIVER, "silpose.datagen.testing:slow_render_samples", str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        ready = (lambda: len(worker_processes(proc.pid)) == 2) if victim == "starting" else (lambda: any(started.iterdir()))
        while not ready():
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()[1][-2000:]
            time.sleep(0.01)
        announced = {int(p.name) for p in started.iterdir()}
        candidates = [w for w in worker_processes(proc.pid) if (w.pid in announced) == (victim == "busy")]
        target = candidates[0]
        os.kill(target.pid, signal.SIGKILL)
        stdout, stderr = proc.communicate(timeout=60)  # a hang fails here
    finally:
        kill_process_group(proc.pid)  # the driver and any worker left
    assert proc.returncode == 3, stderr[-2000:]
    line = stdout.strip().splitlines()[-1]
    assert line.startswith(f"error worker process {target.pid} died with exit code -9"), line
    assert "train-0000" in line
    assert "Traceback" not in stderr


def test_a_failing_task_names_its_shard_and_stops_the_workers(config):
    with pytest.raises(ExecutorError, match=r"shard test-00000-of-00001.parquet: worker failed: RuntimeError"):
        list(run_local([ShardTask("test", 0, 1, (0, 1), "test-00000-of-00001.parquet")], config,
                       "silpose.datagen.testing:failing_render_samples", workers=1))
    assert workers_alive() == []


def test_spawned_map_answers_every_job_once_and_names_the_job_of_a_dead_worker():
    from silpose.datagen.testing import exit_or_square

    got = dict(spawned_map(exit_or_square, [(k, (0, k)) for k in range(7)], workers=2, max_tasks_per_child=3))
    assert {k: v[0] for k, v in got.items()} == {k: k * k for k in range(7)}
    assert len({v[1] for v in got.values()}) >= 3  # 7 calls, at most 3 per process
    with pytest.raises(WorkerDied) as died:
        list(spawned_map(exit_or_square, [("a", (0, 1)), ("b", (5, 2)), ("c", (0, 3))], workers=2))
    assert died.value.key == "b" and died.value.exitcode == 5
    assert workers_alive() == []


def test_a_worker_that_dies_before_its_first_job_reaches_it_is_reported_with_that_job(monkeypatch):
    """The window the SIGKILL drill above hits only sometimes: the process is gone before the driver
    sends it its first job, so the send fails; the job is reported as the dead worker's, no traceback."""
    from multiprocessing.context import SpawnProcess

    from silpose.datagen.testing import exit_or_square

    start = SpawnProcess.start

    def start_then_die(process):
        start(process)
        process.kill()
        process.join()

    monkeypatch.setattr(SpawnProcess, "start", start_then_die)
    with pytest.raises(WorkerDied) as died:
        list(spawned_map(exit_or_square, [("a", (0, 1)), ("b", (0, 2))], workers=1))
    assert died.value.key == "a" and died.value.exitcode == -signal.SIGKILL
    assert workers_alive() == []
