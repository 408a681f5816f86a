"""The floor plan drawn by a worker process (silpose.app.recordings.floorplan_worker): the same file as drawn in
the run's own process, a failing worker leaves the drawing to the run, and a worker is started only when the
run's process has not imported matplotlib yet."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from silpose.app.recordings.floorplan import write_floorplan
from silpose.app.recordings.floorplan_worker import FloorplanProcess
from silpose.datagen.lab import LAB_TRANSFORM, lab_rig
from silpose.shared.camera import Rig


@pytest.fixture
def tracks() -> dict[int, np.ndarray]:
    rng = np.random.default_rng(3)
    t = np.arange(40.0)
    return {p: np.column_stack([t, np.cumsum(rng.normal(0, 0.05, 40)) + p - 1, 0.03 * t - 0.6 * p])
            for p in (1, 4)} | {7: np.zeros((0, 3))}


def test_the_worker_draws_the_same_png_as_the_run_itself(tmp_path, tracks):
    base = lab_rig()
    rig = Rig(base.cameras, LAB_TRANSFORM, base.workspace, base.source)  # the plan draws the lab's origin and axes
    here = write_floorplan(tmp_path / "here.png", tracks, rig, rig.transform, rig.workspace, "lab: 2 person(s)")
    worker = FloorplanProcess()
    assert worker.draw(tmp_path / "there.png", tracks, rig, "lab: 2 person(s)")
    assert worker.proc.returncode == 0 and not worker.log_path.exists()
    assert (tmp_path / "there.png").read_bytes() == here.read_bytes()


def test_a_failing_worker_returns_false_and_leaves_nothing(tmp_path, tracks):
    (tmp_path / "a file").write_text("not a folder")
    worker = FloorplanProcess()
    assert not worker.draw(tmp_path / "a file" / "plan.png", tracks, lab_rig(), "t")
    assert worker.proc.returncode == 1 and not worker.log_path.exists()
    assert (tmp_path / "a file").read_text() == "not a folder"


def test_a_run_that_ends_without_a_plan_stops_its_worker():
    worker = FloorplanProcess()
    worker.kill()
    assert worker.proc.poll() is not None and not worker.log_path.exists()
    quiet = FloorplanProcess()  # empty input (the run's end of the pipe closed): nothing drawn, exit 0
    quiet.proc.communicate(b"", timeout=120)
    assert quiet.proc.returncode == 0
    quiet.log_path.unlink(missing_ok=True)


def test_a_worker_is_started_only_where_matplotlib_is_not_imported_yet():
    code = ("import sys\nfrom silpose.app.recordings.floorplan_worker import floorplan_process\n"
            "first = floorplan_process()\nimport matplotlib.pyplot\nsecond = floorplan_process()\n"
            "print(first is not None, second is None)\nfirst.kill()\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split() == ["True", "True"]
