"""The lab recording's driver: a rendering that fails or a worker that dies is one error naming the folder, at once.

It used to run :func:`~silpose.datagen.lab.render_lab` in a ``multiprocessing.Pool``, which replaces a dead worker
and loses its task: a worker killed by the OOM killer (or a crash in Blender) left the driver waiting for its
600 s timeout. The drill runs the driver in a child process under a timeout, so a hang fails the test.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import psutil
import pytest

from silpose.datagen.lab import LabRenderError, make_lab_recording
from silpose.datagen.testing import kill_process_group

_DRIVER = """
import sys
from silpose.datagen.lab import LabRenderError, make_lab_recording
try:
    make_lab_recording(sys.argv[1], n_frames=100_000)
except LabRenderError as exc:
    print("error", exc, flush=True)
    sys.exit(3)
"""


def test_a_failing_rendering_is_one_error_naming_the_folder_and_the_cause(tmp_path):
    with pytest.raises(LabRenderError, match=r"lab recording failed: UnknownRendererError: .*'no-such-renderer'") as err:
        make_lab_recording(tmp_path / "lab", n_frames=2, renderer="no-such-renderer")
    assert str(tmp_path / "lab") in str(err.value)
    assert not (tmp_path / "lab" / "truth.npz").exists()


def test_a_worker_killed_mid_rendering_is_reported_at_once(tmp_path):
    out = tmp_path / "lab"
    proc = subprocess.Popen([sys.executable, "-c", _DRIVER, str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not (out / "masks").is_dir():  # the worker is rendering
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()[1][-2000:]
            time.sleep(0.05)
        workers = [p for p in psutil.Process(proc.pid).children()
                   if not any("resource_tracker" in part for part in p.cmdline())]
        assert len(workers) == 1
        workers[0].send_signal(signal.SIGKILL)
        stdout, stderr = proc.communicate(timeout=60)  # a driver waiting for the lost task fails here
    finally:
        kill_process_group(proc.pid)
    assert proc.returncode == 3, stderr[-2000:]
    line = stdout.strip().splitlines()[-1]
    assert line.startswith(f"error {out}: rendering the lab recording failed: worker process {workers[0].pid} died "
                           "with exit code -9"), line
    assert not (out / "truth.npz").exists()
