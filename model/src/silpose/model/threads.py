"""Threads: BLAS held to one thread, and the blocks of a batch inferred on threads of their own.

:func:`one_blas_thread` is a context in which BLAS runs on one thread (threadpoolctl; the limit is process-wide and the
previous one comes back at its end). Its users:

- EM's loops of small products (``silpose.model._em``: a block's (rows, q) x (q, q) per component), where waking
  OpenBLAS's threads costs more than the product. Measured on one block of 852 rows, M 60, q 40, d 1,657 at load ~8:
  ``_ppca.log_prob_from_products`` 0.28 -> 0.057 s wall, 0.14 -> 0.025 s CPU (the same values to rounding, 5e-13
  nats). There one thread computes: never put the limit around code other threads run at once.
- :func:`map_blocks` (robust inference of a large batch, ``silpose.model.robust.loop``): each block of frames on a thread of the process's pool (kept between calls), its
  products on one BLAS thread, so that the threads do not compete with BLAS's own for the cores. numpy releases the
  GIL inside its array loops, which are most of the work. Two callers mapping blocks at once from threads of their
  own share the pool; the BLAS limit is the process's, restored when each leaves.
- plain inference of a large batch (``silpose.model.posterior.Posterior.infer_in_blocks``, and the blocks of
  ``silpose.model.conditioning.Conditioner.__call__``): blocks of at most ``THREAD_BLOCK_ROWS`` (512) frames, each
  normalised, conditioned and denormalised by one thread into arrays the caller's thread allocated, so that the ~35 %
  of its work outside BLAS (contour normalisation, the latent algebra, the pixel reconstructions) runs on every core
  too. An earlier try (whole-batch steps in equal blocks of >= 256 frames) gained nothing at load 7-9 and cost a
  process's first large batch ~100 ms (threads' memory arenas); with blocks of 512 frames and no whole-batch
  temporaries, a call after the first maps no new memory (page faults per 2,000-frame call 2,079 -> 0).

:func:`map_threads` is the pool without the BLAS limit, for numpy's element-wise passes (``silpose.model.features``:
the chunks of a large batch's contour normalisation and denormalisation).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence, TypeVar

from threadpoolctl import ThreadpoolController

__all__ = ["THREADS", "MIN_THREAD_FRAMES", "one_blas_thread", "prepare", "block_bounds", "map_blocks", "map_threads"]

#: threads that infer the blocks of a large batch at once (:func:`map_blocks`); 1 = the blocks one after the other on
#: the caller's thread
THREADS = max(1, min(os.cpu_count() or 1, 8))
#: frames a thread gets at least: a batch of fewer than twice this many runs on the caller's thread (a recording's
#: chunks of a few people, single frames)
MIN_THREAD_FRAMES = 256

_BLAS: list = []  # the process's ThreadpoolController, made on first use (scanning the loaded libraries costs ~10 ms)
_POOL: list = []  # the process's ThreadPoolExecutor for map_blocks and its size, made on first use
_LOCK = threading.Lock()
_IN_POOL = threading.local()  # set on the pool's threads: a block that maps blocks again runs them in place

T = TypeVar("T")
R = TypeVar("R")


def one_blas_thread():
    """A context in which BLAS runs on one thread (module doc); the limit is process-wide."""
    prepare()
    return _BLAS[0].limit(limits=1, user_api="blas")


def prepare() -> None:
    """Make the process's BLAS controller now (``silpose.model.posterior.Posterior`` does, so that a first large
    batch does not pay for it; idempotent)."""
    if not _BLAS:
        with _LOCK:
            if not _BLAS:
                _BLAS.append(ThreadpoolController())


def block_bounds(n: int, max_block: int | None = None) -> tuple[list[tuple[int, int]], int]:
    """The blocks of a batch of ``n`` frames, [(start, stop)], and the threads that infer them: the fewest blocks of at
    most ``max_block`` frames (None: no bound) whose count is a multiple of the threads (each thread gets the same
    share), their sizes equal to one frame; ``min(THREADS, n // MIN_THREAD_FRAMES)`` threads, at least 1."""
    threads = max(1, min(int(THREADS), n // MIN_THREAD_FRAMES))
    count = 1 if max_block is None else max(-(-n // int(max_block)), 1)
    count = min(-(-count // threads) * threads, max(n, 1))
    edges = [i * n // count for i in range(count + 1)]
    return list(zip(edges[:-1], edges[1:])), threads


def _pool(threads: int) -> ThreadPoolExecutor:
    """The process's pool of at least ``threads`` threads (kept between calls: starting threads costs ~ms)."""
    with _LOCK:
        if not _POOL or _POOL[0][1] < threads:
            if _POOL:
                _POOL.pop()[0].shutdown(wait=False)
            _POOL.append((ThreadPoolExecutor(max_workers=threads, thread_name_prefix="silpose-block",
                                             initializer=_mark_pool_thread), threads))
        return _POOL[0][0]


def _mark_pool_thread() -> None:
    _IN_POOL.active = True


def map_blocks(fn: Callable[[T], R], blocks: Sequence[T], threads: int) -> list[R]:
    """``[fn(b) for b in blocks]``, on ``threads`` threads of the process's pool when more than one (and more than one
    block), BLAS on one thread meanwhile (module doc); in place on the caller's thread otherwise, and when the caller
    is itself one of the pool's threads. ``fn`` must give each block's answer from that block alone; the first
    exception raised is raised here."""
    threads = min(int(threads), len(blocks))
    if threads <= 1 or getattr(_IN_POOL, "active", False):
        return [fn(b) for b in blocks]
    with one_blas_thread():
        return map_threads(fn, blocks, threads)


def map_threads(fn: Callable[[T], R], items: Sequence[T], threads: int) -> list[R]:
    """``[fn(x) for x in items]`` on ``threads`` threads of the process's pool, BLAS left as it is: for numpy's
    element-wise passes over a large batch (``silpose.model.features``' contour normalisation), whose loops release the
    GIL. In place on the caller's thread when one thread or one item, and when the caller is one of the pool's threads
    (e.g. a block of :func:`map_blocks`). ``fn`` must write disjoint outputs; the first exception raised is raised
    here."""
    threads = min(int(threads), len(items))
    if threads <= 1 or getattr(_IN_POOL, "active", False):
        return [fn(x) for x in items]
    return list(_pool(threads).map(fn, items))
