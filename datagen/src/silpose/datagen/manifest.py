"""The dataset folder's ``manifest.json`` and its write lock.

The manifest records the config, the seeds, the per-split counts, every shard's sha256, row count,
sample-id range and redraw count, and the timing of the run that completed the dataset.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import socket
import time
from pathlib import Path

from silpose.shared.dataset import SHARD_RE, DatasetError, read_metadata

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


def read_manifest(root: Path) -> dict:
    path = Path(root) / MANIFEST
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: manifest not found") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None


def is_dataset_folder(root: Path) -> bool:
    """True if ``root`` is recognisably a dataset written by ``silpose gen`` before output folders
    carried the marker of :mod:`silpose.shared.output_dir`: its ``manifest.json`` is a silpose manifest,
    or (an interrupted run) it holds only silpose shards, their temporaries and the lock file."""
    root = Path(root)
    try:
        manifest = read_manifest(root)
    except (FileNotFoundError, ValueError):
        manifest = None
    if isinstance(manifest, dict) and "manifest_version" in manifest and isinstance(manifest.get("shards"), list):
        return True
    entries = list(root.iterdir())
    for p in entries:
        if p.name == LOCK or (p.name.startswith(".") and p.name.endswith(".tmp") and SHARD_RE.match(p.name[1:].rsplit(".", 2)[0])):
            continue
        if not (SHARD_RE.match(p.name) and p.is_file()):
            return False
        try:
            read_metadata(p)
        except DatasetError:
            return False
    return bool(entries)


class FolderLock:
    """An exclusive lock on a dataset folder: ``fcntl.flock`` on the lock file ``LOCK``.

    The kernel holds the lock, not the file's content: it is released when the holder exits,
    however it dies (SIGKILL, OOM), so a lock file left by a dead run is simply taken over, and a
    live holder can never be displaced (an earlier check-the-pid-then-unlink scheme let two runs
    that found the same stale file both take the lock, and refused forever when a dead run's pid
    had been reused). The file records the holder (pid, host, start time) for the error message
    of a second run, which refuses with a LockError. The file is removed on release; a run that
    locked a file just unlinked by a releasing holder notices (inode changed) and retries.
    """

    def __init__(self, root: Path):
        self.path = Path(root) / LOCK
        self.held = False
        self._fd: int | None = None

    def _holder(self, fd: int) -> dict:
        try:
            holder = json.loads(os.pread(fd, 4096, 0) or b"{}")
        except (OSError, ValueError):
            return {}
        return holder if isinstance(holder, dict) else {}

    def acquire(self) -> None:
        info = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        for _ in range(10):
            fd = os.open(self.path, os.O_CREAT | os.O_RDWR, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = self._holder(fd)
                os.close(fd)
                raise LockError(
                    f"{self.path}: another 'silpose gen' (pid {holder.get('pid', '?')} on {holder.get('host', '?')}, "
                    f"started {holder.get('started', '?')}) is writing this folder; wait for it to finish"
                ) from None
            try:
                current = os.stat(self.path).st_ino
            except FileNotFoundError:
                current = None
            if current != os.fstat(fd).st_ino:  # we locked a file its holder unlinked on release
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(info).encode(), 0)
            self._fd, self.held = fd, True
            return
        raise LockError(f"{self.path}: could not take the lock")

    def release(self) -> None:
        if self.held:
            self.path.unlink(missing_ok=True)  # before unlocking: a waiting run then sees the inode change
            os.close(self._fd)
            self._fd, self.held = None, False

    def __enter__(self) -> "FolderLock":
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()
