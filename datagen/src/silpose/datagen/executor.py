"""Run shard tasks in worker processes: a local spawn pool or Ray tasks.

A task renders one shard: ``render(config, split, indices) -> list[record]`` where ``render``
is named by a ``"module:function"`` string (default ``silpose.datagen.worker:render_samples``)
and imported inside the worker. The driver never imports bpy (docs/conventions.md, "Blender"):
workers are spawned, never forked, and the render module is imported only in them.

Executors yield ``(task, result)`` as tasks finish (any order); a result is a dict with
``records``, ``seconds`` (render wall time), ``pid`` and ``rss_mb`` of the worker after the task.
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterable, Iterator

import psutil

DEFAULT_RENDER = "silpose.datagen.worker:render_samples"
#: Shard tasks a worker runs before it is replaced (bounds memory growth in long runs).
DEFAULT_MAX_TASKS_PER_CHILD = 20


@dataclass(frozen=True)
class ShardTask:
    """One shard to render: ``indices`` of ``split`` written to ``file`` (a name, not a path)."""

    split: str
    shard: int
    n_shards: int
    indices: tuple[int, ...]
    file: str


class ExecutorError(RuntimeError):
    """A worker failed; the message names the shard and the worker's error."""


def _resolve(target: str):
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)


def run_task(target: str, config: dict, split: str, indices: list[int]) -> dict:
    """Worker side: render one shard with ``target`` and time it."""
    t0 = time.perf_counter()
    records = _resolve(target)(config, split, list(indices))
    seconds = time.perf_counter() - t0
    rss_mb = psutil.Process().memory_info().rss / 2**20
    return {"records": records, "seconds": seconds, "pid": os.getpid(), "rss_mb": rss_mb}


def _run_task_star(args: tuple) -> tuple:
    task, target, config = args
    try:
        return task, run_task(target, config, task.split, list(task.indices)), None
    except Exception as exc:  # report which shard failed; the driver raises
        return task, None, f"{type(exc).__name__}: {exc}"


def ignore_interrupt() -> None:
    """Pool initializer: a worker ignores SIGINT. Ctrl-C reaches the terminal's whole process group; only
    the driver handles it (its command prints one line and the pool is terminated), so the workers do
    not each print a KeyboardInterrupt traceback."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def _interrupt_ignored_by_children():
    """While the pool spawns its workers, ignore SIGINT here: an ignored signal stays ignored across
    exec, so the children are immune from their first instruction (before ``ignore_interrupt`` runs)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def default_workers() -> int:
    """All cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def run_local(
    tasks: Iterable[ShardTask],
    config: dict,
    target: str = DEFAULT_RENDER,
    workers: int | None = None,
    max_tasks_per_child: int = DEFAULT_MAX_TASKS_PER_CHILD,
) -> Iterator[tuple[ShardTask, dict]]:
    """Run ``tasks`` on a ``multiprocessing`` spawn pool of ``workers`` processes (default: all cores).

    Uses ``Pool(maxtasksperchild=...)``, not ``ProcessPoolExecutor(max_tasks_per_child=...)``, which
    can deadlock on Python 3.11 (docs/conventions.md, "Blender").
    """
    tasks = list(tasks)
    if not tasks:
        return
    n = min(workers or default_workers(), len(tasks))
    ctx = multiprocessing.get_context("spawn")
    with _interrupt_ignored_by_children():
        pool = ctx.Pool(processes=n, maxtasksperchild=max_tasks_per_child, initializer=ignore_interrupt)
    try:
        pending = [(t, pool.apply_async(_run_task_star, ((t, target, config),))) for t in tasks]
        seen: dict[int, object] = {}
        while pending:
            pending[0][1].wait(WATCHDOG_SECONDS)
            for item in [p for p in pending if p[1].ready()]:
                pending.remove(item)
                task, result, error = item[1].get()
                if error is not None:
                    raise ExecutorError(f"shard {task.file}: worker failed: {error}")
                yield task, result
            _check_workers_alive(pool, seen, [t for t, _ in pending])
        pool.close()
    finally:
        pool.terminate()
        pool.join()


#: How often the driver checks that no pool worker died (seconds).
WATCHDOG_SECONDS = 0.2


def _check_workers_alive(pool, seen: dict, unfinished: list[ShardTask]) -> None:
    """Raise ExecutorError if a pool worker died abnormally (a crash in Blender, the OOM killer).

    ``multiprocessing.Pool`` silently replaces a dead worker and loses its task, so waiting for
    that task would hang forever. Workers retired by ``maxtasksperchild`` exit with code 0.
    Reads the pool's worker list (``Pool._pool``, the only way to see them); the processes are
    remembered so a worker already reaped and replaced by the pool is still checked.
    """
    for proc in list(getattr(pool, "_pool", [])):
        seen.setdefault(proc.pid, proc)
    for pid, proc in seen.items():
        code = proc.exitcode
        if code not in (None, 0):
            names = ", ".join(t.file for t in unfinished[:3]) + (" ..." if len(unfinished) > 3 else "")
            raise ExecutorError(
                f"worker process {pid} died with exit code {code} while rendering; unfinished shard(s): {names}"
            )


def run_ray(
    tasks: Iterable[ShardTask],
    config: dict,
    target: str = DEFAULT_RENDER,
    workers: int | None = None,
    max_tasks_per_child: int = DEFAULT_MAX_TASKS_PER_CHILD,
) -> Iterator[tuple[ShardTask, dict]]:
    """Run ``tasks`` as Ray tasks (``ray.remote``), at most ``2 * workers`` in flight.

    Uses the running Ray instance if ``ray.init`` was called (or ``RAY_ADDRESS`` is set), else
    starts a local one with ``workers`` CPUs. Each Ray worker process runs at most
    ``max_tasks_per_child`` tasks (``max_calls``) to bound memory.
    """
    # Ray >= 2.43 re-runs a driver started with `uv run` as `uv run` in every worker (a synced
    # copy of the working directory); that re-syncs the environment per worker and, on a busy
    # machine, misses Ray's 60 s registration timeout. Workers use this interpreter instead.
    os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
    try:
        import ray
    except ImportError:
        raise ExecutorError("executor 'ray': ray is not installed (install the 'ray' extra)") from None
    tasks = list(tasks)
    if not tasks:
        return
    if not ray.is_initialized():
        if os.environ.get("RAY_ADDRESS"):
            ray.init()
        else:
            ray.init(num_cpus=workers or default_workers(), include_dashboard=False, log_to_driver=False)
    remote = ray.remote(num_cpus=1, max_calls=max_tasks_per_child)(run_task)
    config_ref = ray.put(config)
    in_flight_limit = 2 * (workers or max(1, int(ray.cluster_resources().get("CPU", 1))))
    pending: dict = {}
    queue = list(tasks)
    try:
        while queue or pending:
            while queue and len(pending) < in_flight_limit:
                t = queue.pop(0)
                pending[remote.remote(target, config_ref, t.split, list(t.indices))] = t
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                task = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except Exception as exc:
                    msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
                    raise ExecutorError(f"shard {task.file}: Ray task failed: {msg}") from None
                yield task, result
    finally:
        for ref in pending:
            try:
                ray.cancel(ref, force=True)
            except Exception:  # already finished or gone
                pass


EXECUTORS = {"local": run_local, "ray": run_ray}
