"""Out-of-core MPPCA training: a dataset's Parquet shards as the row blocks of EM, locally or on Ray.

:class:`DatasetShards` is a :class:`~silpose.model.shards.ShardSource` over one split of a silpose
dataset. Each EM pass reads every shard (``silpose.shared.dataset.read_shard``: contours and joints
only), builds its shape vectors with the model's own feature construction
(``silpose.model.features.shape_vectors``: view selection, contour normalisation, structure
weight) and hands them to one EM task (``silpose.model._em``); only the task's small result (the
EM sums, O(d M q)) outlives the shard. With ``executor="local"`` the shards are read one after the
other in this process, so at most one shard's features exist at a time. With ``executor="ray"``
each shard is a Ray task (at most ``2 x CPUs`` in flight; results summed in shard order, so the
fit equals the local one up to BLAS rounding). Ray is imported only then; silpose-model does not
depend on it (the ``ray`` extra).

**Feature cache** (``feature_cache()``, used by ``ShapeStructureModel.fit_stream`` with the local executor):
building a shard's vectors costs about 40 ms of CPU per 200 rows (Parquet decoding, contour
normalisation), paid again in every EM pass (about 10 s per pass at 48,000 rows). Inside the context the
first pass writes each shard's vectors (all its rows, float64, before row selection and centring) as one
``.npy`` file (written atomically, ``silpose.shared.atomic``) in a temporary folder of its own
(``silpose-features-*`` under the system's temporary folder, removed when the context exits, also on an
error); later passes ``np.load`` the file (``allow_pickle=False``, memory-mapped) and take their rows
from it, so memory stays bounded by one shard, as without the cache. The cached values are the
features bit for bit (float64; float32 would halve the disk, 636 MB at 48,000 rows of d 1,657, but
move the fit by float32 rounding), so the fit equals the uncached one exactly. Ray tasks, which may
run on other machines, never use it.

Before training, the plan reads only the shards' footers: row counts and metadata, checked to agree
across shards (the file is named in every error). ``ShapeStructureModel.fit_stream`` plans the
shards and fits on them.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from silpose.shared.atomic import atomic_open
from silpose.shared.camera import Rig
from silpose.shared.dataset import DatasetError, list_shards, read_metadata, read_shard, rig_from_metadata, shard_name
from silpose.shared.ray_tasks import cancel_pending, task_failure_message

from .features import FeatureLayout, shape_vectors
from .shards import ShardSource, compose_rows

EXECUTORS = ("local", "ray")
_SAME_METADATA = ("format_version", "cameras", "n_points", "joint_names", "config")


class StreamingError(RuntimeError):
    """A streaming or Ray training task failed; the message names the shard file."""


def load_shard_features(path: str, rows, layout: FeatureLayout, n_rig_views: int) -> np.ndarray:
    """Shape vectors (n, d) float64 of one shard file (its ``rows``, sorted local indices, or all if None)."""
    shard = read_shard(path, columns=["joints", "contours"])
    contours, joints, rig = shard.contours, shard.joints, shard.rig
    del shard
    if rows is not None:
        contours, joints = contours[rows], joints[rows]
    return shape_vectors(layout, n_rig_views, contours, joints, rig)


def cached_shard_features(cache: str, index: int, path: str, rows, layout: FeatureLayout,
                          n_rig_views: int) -> np.ndarray:
    """:func:`load_shard_features` through the cache folder ``cache``: shard ``index``'s vectors (all rows)
    are built and saved as ``shard-<index>.npy`` on first use, then read back memory-mapped; returns the
    ``rows`` (or all) as a float64 array of its own (the mapping is released on return)."""
    file = Path(cache) / f"shard-{index:05d}.npy"
    if not file.exists():
        X = load_shard_features(path, None, layout, n_rig_views)
        with atomic_open(file, "wb") as fh:
            np.save(fh, X, allow_pickle=False)
        return X if rows is None else X[rows]
    mm = np.load(file, mmap_mode="r", allow_pickle=False)
    if mm.ndim != 2 or mm.shape[1] != layout.dim or mm.dtype != np.float64:
        raise StreamingError(f"{file}: cached features of {path} have shape {mm.shape} {mm.dtype}, "
                             f"expected (rows, {layout.dim}) float64")
    return np.array(mm if rows is None else mm[rows], dtype=np.float64)


def run_shard_task(path: str, rows, layout: FeatureLayout, n_rig_views: int, offset, fn: Callable, args: tuple,
                   first: tuple = (), cache: tuple | None = None):
    """One EM task: ``fn(features of the shard - offset, *first, *args)``. Runs in this process or in a Ray worker.
    ``cache``: (folder, shard index) to read the features through :func:`cached_shard_features` (local only)."""
    if cache is None:
        X = load_shard_features(path, rows, layout, n_rig_views)
    else:
        X = cached_shard_features(cache[0], cache[1], path, rows, layout, n_rig_views)
    if offset is not None:
        X -= offset
    return fn(X, *first, *args)


@dataclass(frozen=True)
class DatasetShards(ShardSource):
    """One split of a dataset as EM row blocks. Build with :meth:`open`, then :meth:`with_layout`.

    Attributes: paths (shard files, in order), n_rows (rows per file), metadata (the first shard's
    ``silpose`` document), layout (FeatureLayout or None until set), rows (per shard: sorted local
    row indices or None = all), offset ((d,) subtracted from every row, or None), executor
    ("local" or "ray"), workers (Ray CPUs when this process starts Ray; None = all cores), cache (the
    feature cache's folder inside :meth:`feature_cache`, else None).
    """

    paths: tuple[str, ...]
    n_rows: tuple[int, ...]
    metadata: dict
    layout: FeatureLayout | None = None
    rows: tuple = ()
    offset: np.ndarray | None = None
    executor: str = "local"
    workers: int | None = None
    cache: str | None = None

    @classmethod
    def open(cls, root: str | Path, split: str = "train", *, executor: str = "local",
             workers: int | None = None) -> "DatasetShards":
        """Plan over the shards of ``split`` in ``root``: reads footers only (metadata, row counts)."""
        if executor not in EXECUTORS:
            raise ValueError(f"executor must be one of {EXECUTORS}, got {executor!r}")
        files = list_shards(root, split)
        if not files:
            raise DatasetError(f"{root}: no shards for split {split!r} ({shard_name(split, 0, 1)} ...)")
        first = read_metadata(files[0])
        n_rows = []
        for path in files:
            meta = first if path == files[0] else read_metadata(path)
            for key in _SAME_METADATA:
                if meta.get(key) != first.get(key):
                    raise DatasetError(f"{path}: metadata field {key!r} differs from the split's first shard")
            try:
                n_rows.append(int(pq.read_metadata(path).num_rows))
            except (pa.ArrowException, OSError, ValueError) as exc:  # ValueError: UnicodeDecodeError too
                raise DatasetError(f"{path}: not a readable Parquet file ({exc})") from None
        return cls(tuple(str(p) for p in files), tuple(n_rows), first, rows=(None,) * len(files),
                   executor=executor, workers=workers)

    # ------------------------------------------------------------------ dataset facts
    @property
    def rig(self) -> Rig:
        return rig_from_metadata(self.metadata)  # cameras, and the transform / workspace of an imported rig

    @property
    def n_rig_views(self) -> int:
        return len(self.metadata["cameras"])

    @property
    def n_points(self) -> int:
        return int(self.metadata["n_points"])

    def with_layout(self, layout: FeatureLayout) -> "DatasetShards":
        if not all(0 <= v < self.n_rig_views for v in layout.views):
            raise ValueError(f"views {layout.views} do not all exist: the data have {self.n_rig_views} views")
        if layout.n_points != self.n_points:
            raise ValueError(f"layout has {layout.n_points} contour points, the data {self.n_points}")
        return replace(self, layout=layout)

    @contextmanager
    def feature_cache(self) -> Iterator["DatasetShards"]:
        """This source with its shards' vectors cached in a temporary folder (module doc; local executor
        only: with "ray" the source is yielded unchanged). The folder is removed on exit."""
        if self.executor != "local":
            yield self
            return
        if self.layout is None:
            raise RuntimeError("DatasetShards: call with_layout() before feature_cache()")
        folder = tempfile.mkdtemp(prefix="silpose-features-")
        try:
            yield replace(self, cache=folder)
        finally:
            shutil.rmtree(folder, ignore_errors=True)

    # ------------------------------------------------------------------ ShardSource
    @property
    def n_features(self) -> int:
        if self.layout is None:
            raise RuntimeError("DatasetShards: call with_layout() before reading features")
        return self.layout.dim

    def shard_rows(self) -> list[int]:
        return [n if r is None else len(r) for n, r in zip(self.n_rows, self.rows)]

    def centred(self, offset: np.ndarray) -> "DatasetShards":
        base = 0.0 if self.offset is None else self.offset
        return replace(self, offset=base + np.asarray(offset, dtype=np.float64))

    def select(self, rows: Sequence[np.ndarray]) -> "DatasetShards":
        if len(rows) != len(self.paths):
            raise ValueError(f"select: {len(rows)} row lists for {len(self.paths)} shards")
        return replace(self, rows=tuple(compose_rows(cur, r) for cur, r in zip(self.rows, rows)))

    def map(self, fn: Callable, *args, each: Sequence[tuple] | None = None) -> Iterator:
        todo = [s for s, n in enumerate(self.shard_rows()) if n]
        if self.executor == "ray":
            yield from _ray_map(self, todo, fn, args, each)
            return
        for s in todo:
            yield run_shard_task(self.paths[s], self.rows[s], self.layout, self.n_rig_views, self.offset, fn, args,
                                 each[s] if each is not None else (), None if self.cache is None else (self.cache, s))


# ---------------------------------------------------------------------------- Ray


def start_ray(workers: int | None = None):
    """The ``ray`` module, initialised: the running instance (``ray.init`` called, or ``RAY_ADDRESS``
    set), else a local one with ``workers`` CPUs (default all cores). StreamingError if ray is missing."""
    # Ray >= 2.43 would start every worker of a `uv run` driver with `uv run` (a re-synced copy of
    # the environment per worker); workers use this interpreter instead (as silpose.datagen.executor).
    os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
    try:
        import ray
    except ImportError:
        raise StreamingError("executor 'ray': ray is not installed (install silpose-model[ray], "
                             "or use --executor local)") from None
    if not ray.is_initialized():
        if os.environ.get("RAY_ADDRESS"):
            ray.init()
        else:
            ray.init(num_cpus=workers or max(1, len(os.sched_getaffinity(0))), include_dashboard=False,
                     log_to_driver=False)
    return ray


def _ray_map(src: DatasetShards, todo: list[int], fn: Callable, args: tuple, each=None) -> Iterator:
    """Run ``run_shard_task`` for the shards ``todo`` as Ray tasks; yield results in shard order.

    At most ``limit`` tasks are ahead of the next result to yield, so at most ``limit`` results
    wait on the driver (out-of-order arrivals are held until their turn).
    """
    ray = start_ray(src.workers)
    remote = ray.remote(num_cpus=1)(run_shard_task)
    layout_ref, offset_ref, args_ref = ray.put(src.layout), ray.put(src.offset), ray.put(args)
    limit = 2 * max(1, int(ray.cluster_resources().get("CPU", 1)))
    pending: dict = {}
    ready: dict[int, object] = {}
    nxt = sub = 0
    try:
        while nxt < len(todo):
            while sub < len(todo) and sub < nxt + limit:
                s = todo[sub]
                ref = remote.remote(src.paths[s], src.rows[s], layout_ref, src.n_rig_views, offset_ref, fn, args_ref,
                                    each[s] if each is not None else ())
                pending[ref] = sub
                sub += 1
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                k = pending.pop(ref)
                try:
                    ready[k] = ray.get(ref)
                except Exception as exc:
                    raise StreamingError(f"{src.paths[todo[k]]}: Ray task failed: {task_failure_message(exc)}") from None
            while nxt in ready:
                yield ready.pop(nxt)
                nxt += 1
    finally:
        cancel_pending(ray, pending)
