"""The floor plan drawn in a process of its own, which imports matplotlib while the run goes on.

Importing matplotlib takes ~0.4 s of one core, a sixth of a 150-step mask recording's time, and a run
pays it at its very end, when nothing else overlaps it. When the run's process has not imported matplotlib yet,
:func:`floorplan_process` starts ``python -m silpose.app.recordings.floorplan_worker`` at the run's set-up. The
worker imports matplotlib at once, on the core the run leaves idle. At the end it receives one JSON message on its
standard input and draws the plan (:func:`.floorplan.write_floorplan`). The message is ``{"path": str, "title": str,
"rig": Rig.to_dict(), "tracks": {person: [[frame, x, y], ...]}}``. An empty input (the run stopped early) draws
nothing and exits 0. Any error is one line on standard error and exit status 1.

:meth:`FloorplanProcess.draw` returns False when the worker failed, and the run then draws the plan itself: the
file is the same either way.

Measured with ``silpose infer --videos`` in fresh processes on the 2-core machine, alternating runs with the plan
drawn in the run's process and drawn by the worker:
- the lab recording (4 x 644x486 mask videos, 150 steps, the 400-walker benchmark model, ``--masks --overlays
  none``), six pairs: 53.8-61.6 time steps/s (mean 58.1) against 53.5-68.1 (mean 62.9). The run's ``finish``
  went from 0.5-0.7 s to 0.2-0.4 s; the worker's import slows the steps a little, since it shares the cores;
- Pose2Sim's single-person demo (4 colour videos, mp4 overlays, a 3,000-sample model of its rig), two pairs:
  11.4 / 11.3 against 12.2 / 11.8.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from silpose.shared.camera import Rig

from .overlay_video import worker_env

__all__ = ["FloorplanProcess", "floorplan_process", "main"]

#: seconds :meth:`FloorplanProcess.draw` waits for the worker before the run draws the plan itself.
DRAW_TIMEOUT_S = 120.0


class FloorplanProcess:
    """The worker process (module docstring), started at once; its standard error goes to a temporary file."""

    def __init__(self):
        fd, log = tempfile.mkstemp(prefix="silpose-floorplan-", suffix=".log")
        self.log_path = Path(log)
        try:
            with os.fdopen(fd, "wb") as stderr:
                self.proc = subprocess.Popen([sys.executable, "-m", "silpose.app.recordings.floorplan_worker"],
                                             stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=stderr,
                                             env=worker_env())
        except BaseException:
            self.log_path.unlink(missing_ok=True)
            raise

    def draw(self, path: Path, tracks: dict[int, np.ndarray], rig: Rig, title: str) -> bool:
        """Have the worker draw the plan into ``path`` (tracks: {person: (T, 3) frame, x, y}, metres). Returns True
        when it did, False when it failed (it is stopped then; the caller draws the plan itself)."""
        msg = {"path": str(path), "title": str(title), "rig": rig.to_dict(),
               "tracks": {str(int(p)): np.asarray(t, float).reshape(-1, 3).tolist() for p, t in tracks.items()}}
        try:
            self.proc.communicate(json.dumps(msg).encode(), timeout=DRAW_TIMEOUT_S)
        except (OSError, ValueError, subprocess.TimeoutExpired):
            self.kill()
            return False
        finally:
            self.log_path.unlink(missing_ok=True)
        return self.proc.returncode == 0 and Path(path).is_file()

    def kill(self) -> None:
        """Stop the worker now (the run ended without a plan, or the worker failed)."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        try:
            self.proc.stdin.close()
        except (OSError, ValueError):
            pass
        self.log_path.unlink(missing_ok=True)


def floorplan_process() -> FloorplanProcess | None:
    """A worker when this process has not imported matplotlib's pyplot yet (module docstring), else None: the plan
    is then drawn here, at no import cost. None too when the worker cannot be started."""
    if "matplotlib.pyplot" in sys.modules:
        return None
    try:
        return FloorplanProcess()
    except OSError:
        return None


def main() -> int:
    """The worker (module docstring). Returns the exit status."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the run's: the run stops the worker
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot  # the import the run does not wait for

        from .floorplan import write_floorplan

        text = sys.stdin.read()
        if not text.strip():
            return 0
        msg = json.loads(text)
        rig = Rig.from_dict(msg["rig"])
        tracks = {int(p): np.asarray(t, float).reshape(-1, 3) for p, t in msg["tracks"].items()}
        write_floorplan(Path(msg["path"]), tracks, rig, rig.transform, rig.workspace, str(msg["title"]))
    except Exception as exc:  # noqa: BLE001 - reported as one line; the run draws the plan itself
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
