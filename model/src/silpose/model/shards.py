"""Row blocks ("shards") that the MPPCA's EM maps over: the interface and the in-memory version.

A :class:`ShardSource` yields its rows as float64 blocks (n_s, d), one at a time, as often as EM
asks (one pass per iteration). ``map(fn, *args)`` applies ``fn(block, *args)`` to every block and
yields the results **in shard order** (the driver sums them in that order, so every executor gives
the same rounding). The in-memory fit uses :class:`ArrayShards` with one array; the streaming fit
uses ``silpose.model.streaming.DatasetShards`` (Parquet shards, locally or on Ray).

``centred(offset)`` gives a source whose blocks are ``rows - offset`` (computed per block, so only
one block's copy exists at a time); ``select(rows)`` one that yields only the given local rows of
each shard (the initialisation subsample).
"""

from __future__ import annotations

from typing import Callable, Iterator, Sequence

import numpy as np


class ShardSource:
    """Interface: a re-iterable sequence of row blocks with ``n_features`` columns."""

    n_features: int

    def shard_rows(self) -> list[int]:
        """Rows each shard yields (after any row selection), in shard order."""
        raise NotImplementedError

    def map(self, fn: Callable, *args, each: Sequence[tuple] | None = None) -> Iterator:
        """``fn(block (n_s, d) float64, *args)`` for every shard with rows, results in shard order.
        ``each``: one tuple per shard (all shards, in order), passed first: ``fn(block, *each[s], *args)``
        (per-shard state, e.g. the sparse E-step's candidate components)."""
        raise NotImplementedError

    def centred(self, offset: np.ndarray) -> "ShardSource":
        """The same rows minus ``offset`` (d,)."""
        raise NotImplementedError

    def select(self, rows: Sequence[np.ndarray]) -> "ShardSource":
        """Only ``rows[s]`` (sorted local indices, relative to this source's rows) of each shard s."""
        raise NotImplementedError


def split_global_rows(idx: np.ndarray, shard_rows: Sequence[int]) -> list[np.ndarray]:
    """Sorted global row indices ``idx`` over shards of ``shard_rows`` rows -> local indices per shard."""
    bounds = np.concatenate([[0], np.cumsum(shard_rows)])
    return [idx[(idx >= lo) & (idx < hi)] - lo for lo, hi in zip(bounds[:-1], bounds[1:])]


def compose_rows(current: np.ndarray | None, rows: np.ndarray) -> np.ndarray:
    """Rows ``rows`` of a selection ``current`` (local indices, or None = all rows): the composed selection."""
    rows = np.asarray(rows, dtype=np.intp)
    return rows if current is None else current[rows]


class ArrayShards(ShardSource):
    """Arrays in memory as shards: ``arrays`` is a list of (n_s, d) array-likes of finite numbers.

    Blocks are converted to float64 (and checked finite, naming the shard) when EM reads them.
    ``materialise=True`` (the in-memory fit) makes ``centred`` compute the centred copies once
    instead of per pass: faster, at the cost of holding them (one copy of the data, as before).
    """

    def __init__(self, arrays: Sequence, *, materialise: bool = False, _rows=None, _offset=None, _checked=False):
        self._arrays = list(arrays)
        if not self._arrays:
            raise ValueError("MPPCA: no shards given")
        dims = set()
        for s, a in enumerate(self._arrays):
            shape = np.shape(a)
            if len(shape) != 2 or shape[1] < 1:
                raise ValueError(f"MPPCA: shard {s} must be a 2-D array (rows, features), got shape {shape}")
            dims.add(shape[1])
        if len(dims) != 1:
            raise ValueError(f"MPPCA: shards have different feature counts {sorted(dims)}")
        self.n_features = dims.pop()
        self._rows = list(_rows) if _rows is not None else [None] * len(self._arrays)
        self._offset = _offset
        self._checked = _checked
        self._materialise = materialise

    def _clone(self, rows, offset) -> "ArrayShards":
        return ArrayShards(self._arrays, materialise=self._materialise, _rows=rows, _offset=offset,
                           _checked=self._checked)

    def shard_rows(self) -> list[int]:
        return [np.shape(a)[0] if r is None else len(r) for a, r in zip(self._arrays, self._rows)]

    def _block(self, s: int) -> np.ndarray:
        X = np.asarray(self._arrays[s], dtype=np.float64)
        if not self._checked and not np.all(np.isfinite(X)):
            raise ValueError(f"MPPCA: shard {s} contains NaN or infinity")
        if self._rows[s] is not None:
            X = X[self._rows[s]]
        return X if self._offset is None else X - self._offset

    def map(self, fn: Callable, *args, each: Sequence[tuple] | None = None) -> Iterator:
        for s, n in enumerate(self.shard_rows()):
            if n:
                yield fn(self._block(s), *(each[s] if each is not None else ()), *args)  # block freed on return

    def centred(self, offset: np.ndarray) -> "ArrayShards":
        base = 0.0 if self._offset is None else self._offset
        out = self._clone(self._rows, base + np.asarray(offset, dtype=np.float64))
        if self._materialise:
            out = ArrayShards([out._block(s) for s in range(len(self._arrays))], materialise=True, _checked=True)
        return out

    def select(self, rows: Sequence[np.ndarray]) -> "ArrayShards":
        if len(rows) != len(self._arrays):
            raise ValueError(f"select: {len(rows)} row lists for {len(self._arrays)} shards")
        return self._clone([compose_rows(cur, r) for cur, r in zip(self._rows, rows)], self._offset)

    def checked(self) -> "ArrayShards":
        """This source with the finiteness check switched off (the caller validated the arrays)."""
        out = self._clone(self._rows, self._offset)
        out._checked = True
        return out
