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
import multiprocessing.connection
import os
import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Iterable, Iterator

import psutil

from silpose.shared.ray_tasks import cancel_pending, task_failure_message

from .blender_env import use_silpose_blender_dirs

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
    use_silpose_blender_dirs()  # before the renderer imports bpy (a Ray worker comes here first)
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


class WorkerDied(RuntimeError):
    """A worker process of :func:`spawned_map` ended without answering (a crash, the OOM killer, SIGKILL).

    Attributes: ``pid``, ``exitcode`` and ``key`` (the key of the job it was running).
    """

    def __init__(self, pid: int, exitcode: int | None, key):
        super().__init__(f"worker process {pid} died with exit code {exitcode}")
        self.pid, self.exitcode, self.key = pid, exitcode, key


def _worker_loop(conn, max_tasks: int, call) -> None:
    """Worker side of :func:`spawned_map`: answer up to ``max_tasks`` messages received on ``conn``
    with ``call(message)``; stop on ``None`` or when the driver is gone."""
    ignore_interrupt()
    use_silpose_blender_dirs()  # Blender's user folders in silpose's cache, before any bpy import
    for _ in range(max_tasks):
        try:
            message = conn.recv()
        except (EOFError, OSError):  # the driver went away
            return
        if message is None:
            return
        conn.send(call(message))
    conn.close()


class _Worker:
    """One spawned worker process, its end of a private pipe, and the key of its job (or None)."""

    def __init__(self, ctx, max_tasks: int, call):
        self.conn, child_conn = ctx.Pipe(duplex=True)
        self.process = ctx.Process(target=_worker_loop, args=(child_conn, max_tasks, call), daemon=True)
        self.process.start()
        child_conn.close()
        self.key = None
        self.busy = False
        self.remaining = max_tasks

    def give(self, key, message) -> None:
        self.key, self.busy = key, True
        self.remaining -= 1
        try:
            self.conn.send(message)
        except OSError:  # it died before its job reached it: the wait loop sees its sentinel and reports it
            pass

    def stop(self, kill: bool) -> None:
        """Ask an idle worker to exit (or kill a busy one) and reap it."""
        if self.process.exitcode is None:
            if kill:
                self.process.kill()
            else:
                try:
                    self.conn.send(None)
                except OSError:
                    self.process.kill()
        self.process.join(timeout=10)
        if self.process.exitcode is None:  # pragma: no cover - a worker that ignored its stop
            self.process.kill()
            self.process.join()
        self.conn.close()


def spawned_map(call, jobs: Iterable[tuple], workers: int | None = None,
                max_tasks_per_child: int = DEFAULT_MAX_TASKS_PER_CHILD) -> Iterator[tuple]:
    """Yield ``(key, call(message))`` for every ``(key, message)`` of ``jobs``, as they finish (any
    order), computed in ``workers`` spawned processes (default: all cores), each replaced after
    ``max_tasks_per_child`` calls (bounds memory growth in Blender).

    ``call`` is a module-level function (spawn pickles it by name); it should return its errors rather
    than raise them. Each worker has a private pipe, and the driver waits on the pipes and the processes'
    sentinels together, so a worker that dies is seen at once: :class:`WorkerDied` names the job's key.
    On any exit (an error, the consumer stopping, Ctrl-C) the workers are stopped and reaped.

    Neither ``multiprocessing.Pool`` (it silently replaces a dead worker and loses its task, and its
    ``terminate()`` can deadlock on the queue lock a killed worker held, CPython issues 73945, 78178
    and 96995) nor ``ProcessPoolExecutor(max_tasks_per_child=...)`` (deadlocks on Python 3.11) is
    used: no lock is shared between processes here (docs/conventions.md, "Blender").
    """
    queue = list(jobs)
    if not queue:
        return
    ctx = multiprocessing.get_context("spawn")
    n = min(workers or default_workers(), len(queue))
    pool: list[_Worker] = []
    failed = True
    try:
        with _interrupt_ignored_by_children():
            pool = [_Worker(ctx, max_tasks_per_child, call) for _ in range(n)]
        for worker in pool:
            worker.give(*queue.pop(0))
        while any(w.busy for w in pool):
            busy = [w for w in pool if w.busy]
            ready = multiprocessing.connection.wait([w.conn for w in busy] + [w.process.sentinel for w in busy])
            for worker in busy:
                if worker.conn not in ready and worker.process.sentinel not in ready:
                    continue
                try:
                    if not worker.conn.poll():  # its process ended without answering
                        raise EOFError
                    reply = worker.conn.recv()
                except (EOFError, OSError):
                    worker.process.join(timeout=5)
                    raise WorkerDied(worker.process.pid, worker.process.exitcode, worker.key) from None
                worker.busy = False
                yield worker.key, reply
                if queue:
                    if worker.remaining == 0:  # retire it; a fresh process takes the next job
                        worker.stop(kill=False)
                        pool.remove(worker)
                        with _interrupt_ignored_by_children():
                            worker = _Worker(ctx, max_tasks_per_child, call)
                        pool.append(worker)
                    worker.give(*queue.pop(0))
        failed = False
    finally:
        for worker in pool:
            worker.stop(kill=failed or worker.busy)


def run_local(
    tasks: Iterable[ShardTask],
    config: dict,
    target: str = DEFAULT_RENDER,
    workers: int | None = None,
    max_tasks_per_child: int = DEFAULT_MAX_TASKS_PER_CHILD,
) -> Iterator[tuple[ShardTask, dict]]:
    """Run ``tasks`` on spawned worker processes (:func:`spawned_map`; default: all cores).

    Raises:
        ExecutorError: a task raised (the message names its shard and the error) or a worker died (it
            names the worker, its exit code and the unfinished shards, the dead worker's first).
    """
    tasks = list(tasks)
    done: set[int] = set()
    try:
        for k, (task, result, error) in spawned_map(_run_task_star, [(k, (t, target, config)) for k, t in enumerate(tasks)],
                                                    workers, max_tasks_per_child):
            if error is not None:
                raise ExecutorError(f"shard {task.file}: worker failed: {error}")
            done.add(k)
            yield task, result
    except WorkerDied as died:
        unfinished = [tasks[died.key]] + [t for k, t in enumerate(tasks) if k not in done and k != died.key]
        names = ", ".join(t.file for t in unfinished[:3]) + (" ..." if len(unfinished) > 3 else "")
        raise ExecutorError(f"{died} while rendering; unfinished shard(s): {names}") from None


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
                    raise ExecutorError(f"shard {task.file}: Ray task failed: {task_failure_message(exc)}") from None
                yield task, result
    finally:
        cancel_pending(ray, pending)


EXECUTORS = {"local": run_local, "ray": run_ray}
