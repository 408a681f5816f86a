"""Drill: Ctrl-C during generation prints the driver's one line, not a traceback per worker.

A terminal's Ctrl-C sends SIGINT to the whole foreground process group: the driver and its spawned
pool workers. The workers ignore it (``silpose.datagen.executor.ignore_interrupt``); the driver stops
and the pool is terminated.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from silpose.datagen.testing import DELAY_ENV, STARTED_ENV, tiny_config_toml, kill_process_group

SLOW = "silpose.datagen.testing:slow_render_samples"

# What `silpose gen` does on Ctrl-C (datagen/cli.py): one line on stderr, exit status 130. The driver
# reacts 1 s late, as when Ctrl-C arrives while it is inside C code (pyarrow writing a shard): Python
# runs its signal handler only when that call returns, while the workers get the signal at once.
_DRIVER = r"""
import signal, sys, time

def late_interrupt(signum, frame):
    time.sleep(1.0)
    raise KeyboardInterrupt

if __name__ == "__main__":
    from silpose.datagen.config import load_config
    from silpose.datagen.pipeline import generate
    signal.signal(signal.SIGINT, late_interrupt)
    try:
        generate(load_config(sys.argv[1]), sys.argv[2], workers=2, render=sys.argv[3], progress=False)
    except KeyboardInterrupt:
        print("silpose gen: error: interrupted", file=sys.stderr)
        sys.exit(130)
"""


def test_ctrl_c_to_the_process_group_prints_no_worker_traceback(tmp_path):
    (tmp_path / "tiny.toml").write_text(tiny_config_toml(train=16, test=4))  # 5 shards of 4 samples
    out, started = tmp_path / "ds", tmp_path / "started"
    started.mkdir()
    env = {**os.environ, DELAY_ENV: "5", STARTED_ENV: str(started)}  # 20 s per shard: Ctrl-C comes mid-shard
    proc = subprocess.Popen([sys.executable, "-c", _DRIVER, str(tmp_path / "tiny.toml"), str(out), SLOW],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True,  # its own process group, like a terminal job
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while len(list(started.iterdir())) < 2:  # both workers are inside the renderer
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()[1][-2000:]
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C
        _, stderr = proc.communicate(timeout=60)
    finally:
        kill_process_group(proc.pid)  # the driver and any worker left
    assert proc.returncode == 130, stderr[-2000:]
    assert stderr.strip().splitlines() == ["silpose gen: error: interrupted"], stderr[-3000:]
