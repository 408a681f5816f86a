"""The dataset folder's ``manifest.json`` and its write lock.

The manifest records the config, the seeds, the per-split counts, every shard's sha256, row count,
sample-id range and redraw count, and the timing of the run that completed the dataset.
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import time
from pathlib import Path

MANIFEST = "manifest.json"
LOCK = ".silpose-gen.lock"
MANIFEST_VERSION = 1


class LockError(RuntimeError):
    """Another run holds the dataset folder."""


def sha256_file(path: Path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def write_json_atomic(path: Path, obj) -> None:
    """Write JSON to a temporary name in the same folder, then ``os.replace``."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(json.dumps(obj, indent=2, sort_keys=False) + "\n")
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def read_manifest(root: Path) -> dict:
    path = Path(root) / MANIFEST
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: manifest not found") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class FolderLock:
    """An exclusive lock file in a dataset folder (``O_CREAT | O_EXCL``).

    A lock left by a dead process on this host (e.g. a run killed with SIGKILL) is stale and is
    taken over; a live one makes the second run refuse with a LockError naming the holder.
    """

    def __init__(self, root: Path):
        self.path = Path(root) / LOCK
        self.held = False

    def acquire(self) -> None:
        info = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                try:
                    holder = json.loads(self.path.read_text())
                except (OSError, json.JSONDecodeError):
                    holder = {}
                if holder.get("host") == info["host"] and isinstance(holder.get("pid"), int) and not _pid_alive(holder["pid"]):
                    self.path.unlink(missing_ok=True)  # stale: its process is gone
                    continue
                raise LockError(
                    f"{self.path}: another 'silpose gen' (pid {holder.get('pid', '?')} on {holder.get('host', '?')}, "
                    f"started {holder.get('started', '?')}) is writing this folder; wait for it to finish"
                ) from None
            with os.fdopen(fd, "w") as f:
                json.dump(info, f)
            self.held = True
            return
        raise LockError(f"{self.path}: could not take the lock")

    def release(self) -> None:
        if self.held:
            self.path.unlink(missing_ok=True)
            self.held = False

    def __enter__(self) -> "FolderLock":
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()
