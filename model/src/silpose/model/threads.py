"""Threads: BLAS held to one thread, and the blocks of a batch inferred on threads of their own.

:func:`one_blas_thread` is a context in which BLAS runs on one thread (threadpoolctl; the limit is process-wide and the
previous one comes back at its end). Two users:

- EM's loops of small products (``silpose.model._em``: a block's (rows, q) x (q, q) per component), where waking
  OpenBLAS's threads costs more than the product. Measured on one block of 852 rows, M 60, q 40, d 1,657 at load ~8:
  ``_ppca.log_prob_from_products`` 0.28 -> 0.057 s wall, 0.14 -> 0.025 s CPU (the same values to rounding, 5e-13
  nats). There one thread computes: never put the limit around code other threads run at once.
- :func:`map_blocks` (robust inference of a large batch, ``silpose.model.robust.loop``): each block of frames on a
  thread of its own, its products on one BLAS thread, so that the threads do not compete with BLAS's own for the
  cores. numpy releases the GIL inside its array loops, which are most of the work.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence, TypeVar

from threadpoolctl import ThreadpoolController

__all__ = ["one_blas_thread", "map_blocks"]

_BLAS: list = []  # the process's ThreadpoolController, made on first use (scanning the loaded libraries costs ~ms)

T = TypeVar("T")
R = TypeVar("R")


def one_blas_thread():
    """A context in which BLAS runs on one thread (module doc); the limit is process-wide."""
    if not _BLAS:
        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1, user_api="blas")


def map_blocks(fn: Callable[[T], R], blocks: Sequence[T], threads: int) -> list[R]:
    """``[fn(b) for b in blocks]``, on ``threads`` threads when more than one (and more than one block), BLAS on one
    thread meanwhile (module doc). ``fn`` must give each block's answer from that block alone; the first exception
    raised is raised here."""
    threads = min(int(threads), len(blocks))
    if threads <= 1:
        return [fn(b) for b in blocks]
    with one_blas_thread(), ThreadPoolExecutor(max_workers=threads) as pool:
        return list(pool.map(fn, blocks))
