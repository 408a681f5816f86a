"""Crash-safe file writes: the one home of "write to a temporary name, then rename".

A reader never sees a half-written file under its final name: every writer in silpose goes
through :func:`atomic_path` (or the helpers built on it), which hands out a temporary sibling
named ``.<name>.<pid>.tmp`` — hidden, and matched by the ``.*.tmp`` pattern that resuming runs
clean up — flushes it to disk, and ``os.replace``s it onto the final name (atomic on POSIX within
one file system). On any exception the temporary file is removed and the final name is left as
it was (the previous version, or absent). See docs/conventions.md, "Crash safety".
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

__all__ = [
    "TMP_GLOB",
    "tmp_name",
    "atomic_path",
    "atomic_open",
    "write_bytes_atomic",
    "write_text_atomic",
    "write_json_atomic",
    "write_figure_atomic",
    "FIGURE_SOFTWARE",
]

#: glob of the temporary files this module creates in a folder (for cleanup of killed runs).
TMP_GLOB = ".*.tmp"


def tmp_name(path: str | Path) -> Path:
    """The temporary sibling of ``path`` this process writes first: ``.<name>.<pid>.tmp``."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path: str | Path, *, mkdir: bool = True) -> Iterator[Path]:
    """Yield a temporary path to write; on success it is fsynced and renamed onto ``path``.

    Use it for writers that want a file name (``pq.write_table``, ``fig.savefig``)::

        with atomic_path(out / "table.parquet") as tmp:
            pq.write_table(table, tmp)

    Args:
        path: the final path.
        mkdir: create the parent folder first.
    """
    path = Path(path)
    if mkdir:
        path.parent.mkdir(parents=True, exist_ok=True)
    tmp = tmp_name(path)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"{path}: the writer created no file at {tmp.name}")
        _fsync(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def atomic_open(path: str | Path, mode: str = "wb", **kwargs: Any) -> Iterator[IO]:
    """``open`` a temporary sibling of ``path`` for writing; renamed onto ``path`` on success.

    Args:
        path: the final path.
        mode: a write mode ("w", "wb", "wt"); keyword arguments go to ``open``.
    """
    if not any(c in mode for c in "wx"):
        raise ValueError(f"atomic_open needs a write mode, got {mode!r}")
    with atomic_path(path) as tmp:
        with open(tmp, mode, **kwargs) as f:
            yield f
            f.flush()


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns ``Path(path)``."""
    with atomic_open(path, "wb") as f:
        f.write(data)
    return Path(path)


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically; returns ``Path(path)``."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def write_json_atomic(path: str | Path, obj: Any, *, indent: int | None = 2, sort_keys: bool = False) -> Path:
    """Write ``obj`` as JSON (plus a final newline) to ``path`` atomically; returns ``Path(path)``."""
    return write_text_atomic(path, json.dumps(obj, indent=indent, sort_keys=sort_keys) + "\n")


#: The PNG ``Software`` text of every figure silpose writes (how a later run recognises its own pictures,
#: ``silpose.shared.output_dir.is_silpose_png``).
FIGURE_SOFTWARE = "silpose"


def write_figure_atomic(fig: Any, path: str | Path, *, dpi: int = 110, tight: bool = False) -> Path:
    """Save a matplotlib figure as PNG to ``path`` atomically and close it (also when saving fails);
    returns ``Path(path)``. The PNG carries ``Software: silpose`` (:data:`FIGURE_SOFTWARE`). ``tight``: ``bbox_inches="tight"``. matplotlib is not imported here: the figure
    saves itself, and it is closed through ``matplotlib.pyplot`` when pyplot is loaded (it made the figure)."""
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png", metadata={"Software": FIGURE_SOFTWARE},
                        **({"bbox_inches": "tight"} if tight else {}))
    finally:
        pyplot = sys.modules.get("matplotlib.pyplot")
        if pyplot is not None:
            pyplot.close(fig)
    return path
