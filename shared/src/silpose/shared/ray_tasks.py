"""Helpers for the Ray task loops of generation (``silpose.datagen.executor``) and streaming EM
(``silpose.model.streaming``). Ray itself is imported by the callers, lazily; nothing here imports it."""

from __future__ import annotations

from typing import Iterable

__all__ = ["cancel_pending", "task_failure_message"]


def cancel_pending(ray, refs: Iterable) -> None:
    """Force-cancel the Ray tasks ``refs`` (a loop that stops early must not leave them running);
    tasks that already finished or vanished are skipped."""
    for ref in refs:
        try:
            ray.cancel(ref, force=True)
        except Exception:  # already finished or gone
            pass


def task_failure_message(exc: BaseException) -> str:
    """The last line of a failed Ray task's error (Ray prefixes the remote traceback), else its type name."""
    lines = str(exc).strip().splitlines()
    return lines[-1] if lines else type(exc).__name__
