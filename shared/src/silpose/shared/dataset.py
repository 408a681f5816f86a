"""Read and write silpose datasets: Parquet shards of multi-view silhouettes and 3D joints.

The format (schema and metadata) is documented in ``silpose.shared.dataset_schema`` and in every
dataset's card; other tools read it without this code (pyarrow, pandas, DuckDB, Polars, HF
``datasets``). This module gives numpy arrays out, zero-copy per Parquet chunk where pyarrow allows
(masks are decoded from their PNG files), and checks every file it reads, naming the file and the
field in its errors. It reads format versions 1 (tensor columns) and 2 (nested lists, PNG masks).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .camera import Rig
from .dataset_schema import (
    ALL_COLUMNS,
    DatasetError,
    check_metadata,
    METADATA_KEY,
    SCALAR_COLUMNS,
    build_metadata,
    column_shapes,
    per_view_fields,
    rig_from_metadata,
)
from .dataset_writer import records_to_table, write_shard
from .mask_png import decode_mask_into

__all__ = [
    "DatasetError",
    "DatasetSplit",
    "build_metadata",
    "iter_shards",
    "list_shards",
    "load_split",
    "read_metadata",
    "read_shard",
    "records_to_table",
    "rig_from_metadata",
    "shard_name",
    "write_shard",
]

SHARD_RE = re.compile(r"^(?P<split>[A-Za-z0-9_]+)-(?P<i>\d{5})-of-(?P<n>\d{5})\.parquet$")
#: Default columns ``load_split`` reads (masks only with ``with_masks=True``).
DEFAULT_COLUMNS = tuple(c for c in ALL_COLUMNS if c != "masks")
#: Columns that must be free of NaN / infinity.
FINITE_COLUMNS = ("joints", "contours", "contour_centroid", "contour_scale", "contour_length")


def shard_name(split: str, i: int, n: int) -> str:
    """``{split}-{i:05d}-of-{n:05d}.parquet``."""
    return f"{split}-{i:05d}-of-{n:05d}.parquet"


# ----------------------------------------------------------------------------- reading


@dataclass
class DatasetSplit:
    """One split (or one shard) of a dataset as numpy arrays. N samples, K views, n contour points.

    Attributes:
        sample_id: (N,) int64.
        joints: (N, 19, 3) float32, world, metres.
        contours: (N, K, n, 2) float32, pixels.
        centroid: (N, K, 2) float32, pixels (contour normalisation offset).
        scale: (N, K) float32, pixels (contour normalisation scale).
        touches_border: (N, K) bool.
        masks: (N, K, H, W) uint8 0/1, or None unless asked for.
        subject, gait: dicts of (N,) float32 arrays.
        extra: other per-sample columns read (seed, redraws, contour_length, area, n_blobs, split).
        rig: the cameras, in view order.
        metadata: the ``silpose`` metadata document.
        files: the shards read, in order.
    """

    sample_id: np.ndarray
    joints: np.ndarray | None
    contours: np.ndarray | None
    centroid: np.ndarray | None
    scale: np.ndarray | None
    touches_border: np.ndarray | None
    masks: np.ndarray | None
    subject: dict[str, np.ndarray]
    gait: dict[str, np.ndarray]
    rig: Rig
    metadata: dict
    files: list[Path] = field(default_factory=list)
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def n_views(self) -> int:
        return len(self.rig)

    @property
    def n_points(self) -> int:
        return int(self.metadata["n_points"])

    def __len__(self) -> int:
        return int(self.sample_id.shape[0])


def list_shards(root: str | Path, split: str) -> list[Path]:
    """The shards ``{split}-{i:05d}-of-{n:05d}.parquet`` of ``split`` under ``root``, in order.

    Raises DatasetError if the shard numbering is incomplete or inconsistent.
    """
    root = Path(root)
    if not root.is_dir():
        raise DatasetError(f"{root}: dataset folder not found")
    found: dict[int, tuple[int, Path]] = {}
    for p in root.iterdir():
        m = SHARD_RE.match(p.name)
        if m and m["split"] == split:
            found[int(m["i"])] = (int(m["n"]), p)
    if not found:
        return []
    totals = {n for n, _ in found.values()}
    if len(totals) != 1:
        raise DatasetError(f"{root}: split {split!r} mixes shard counts {sorted(totals)} in its file names")
    n = totals.pop()
    missing = sorted(set(range(n)) - set(found))
    if missing:
        raise DatasetError(f"{root}: split {split!r} lacks shard(s) {[shard_name(split, i, n) for i in missing[:3]]}")
    return [found[i][1] for i in range(n)]


#: What pyarrow raises on a damaged file: Arrow errors, IO errors, and ValueError (e.g. a
#: UnicodeDecodeError on a flipped byte in a column name in the footer).
_READ_ERRORS = (pa.ArrowException, OSError, ValueError)


def _first_line(exc: Exception) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _open(path: Path) -> pq.ParquetFile:
    """Open a shard, verifying page checksums on every later read (shards are written with them)."""
    try:
        pf = pq.ParquetFile(path, page_checksum_verification=True)
        pf.schema_arrow  # parse the schema now: a damaged footer fails here, naming the file
        return pf
    except _READ_ERRORS as exc:
        raise DatasetError(f"{path}: not a readable Parquet file ({_first_line(exc)})") from None


def _metadata_from_schema(schema: pa.Schema, source: str) -> dict:
    raw = (schema.metadata or {}).get(METADATA_KEY)
    if raw is None:
        raise DatasetError(f"{source}: schema metadata key 'silpose' missing (not a silpose dataset shard)")
    try:
        meta = json.loads(raw)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{source}: schema metadata key 'silpose' is not valid JSON ({exc})") from None
    check_metadata(meta, source)
    return meta


def read_metadata(path: str | Path) -> dict:
    """The validated ``silpose`` metadata document of one shard (reads only the footer)."""
    path = Path(path)
    return _metadata_from_schema(_open(path).schema_arrow, str(path))


def _check_schema(schema: pa.Schema, meta: dict, source: str) -> None:
    cams = meta["cameras"]
    expected = per_view_fields(
        len(cams), int(cams[0]["height"]), int(cams[0]["width"]), int(meta["n_points"]), meta["format_version"]
    )
    expected.update(SCALAR_COLUMNS)
    for name, typ in expected.items():
        idx = schema.get_field_index(name)
        if idx < 0:
            raise DatasetError(f"{source}: column {name!r} missing")
        if not schema.field(idx).type.equals(typ):
            raise DatasetError(f"{source}: column {name!r}: expected type {typ}, got {schema.field(idx).type}")
    for name in ("subject", "gait"):
        idx = schema.get_field_index(name)
        if idx < 0:
            raise DatasetError(f"{source}: column {name!r} missing")
        typ = schema.field(idx).type
        if not pa.types.is_struct(typ) or any(not typ.field(j).type.equals(pa.float32()) for j in range(typ.num_fields)):
            raise DatasetError(f"{source}: column {name!r}: expected a struct of float32, got {typ}")


def _to_numpy(column: pa.ChunkedArray, name: str, row_shape: tuple[int, ...] | None, source: str) -> np.ndarray:
    """(rows, ...) numpy array of a tensor / nested fixed-size-list / PNG-image / scalar column.

    ``row_shape`` is the per-row shape of a per-view column (``column_shapes``), else None.
    """
    chunks = column.chunks or [pa.array([], type=column.type)]
    out = []
    for chunk in chunks:
        if isinstance(chunk.type, pa.FixedShapeTensorType):  # format version 1
            out.append(chunk.to_numpy_ndarray())  # zero-copy per chunk
        elif pa.types.is_fixed_size_list(chunk.type):
            out.append(_nested_to_numpy(chunk, name, row_shape, source))
        else:
            out.append(chunk.to_numpy(zero_copy_only=False))
    return out[0] if len(out) == 1 else np.concatenate(out)


def _nested_to_numpy(chunk: pa.FixedSizeListArray, name: str, row_shape, source: str) -> np.ndarray:
    """Nested fixed-size lists -> (rows, d1, ..., dk), zero-copy for numbers without nulls; a leaf of
    ``{bytes, path}`` image structs (the masks) -> (rows, K, H, W) uint8 decoded from the PNG files."""
    sizes, leaf = [], chunk
    while pa.types.is_fixed_size_list(leaf.type):
        if leaf.null_count:
            raise DatasetError(f"{source}: column {name!r} has {leaf.null_count} null value(s) inside its lists")
        sizes.append(leaf.type.list_size)
        leaf = leaf.flatten()  # respects slice offsets (``.values`` does not)
    if leaf.null_count:
        raise DatasetError(f"{source}: column {name!r} has {leaf.null_count} null value(s) inside its lists")
    if pa.types.is_struct(leaf.type):
        return _decode_images(leaf, (len(chunk), *sizes), tuple(row_shape[len(sizes):]), name, source)
    return leaf.to_numpy(zero_copy_only=False).reshape(len(chunk), *sizes)


def _decode_images(
    images: pa.StructArray, lead: tuple[int, ...], size: tuple[int, int], name: str, source: str
) -> np.ndarray:
    """``lead`` + ``size`` (e.g. (N, K) + (H, W)) uint8 0/1 array from a struct array of N*K PNG files
    ``{bytes, path}``, decoded straight from the Arrow buffers (no Python bytes objects)."""
    blobs = images.field("bytes")
    if len(blobs) == 0:
        return np.empty((*lead, *size), np.uint8)
    if blobs.null_count:
        raise DatasetError(f"{source}: column {name!r}: {blobs.null_count} image(s) without bytes")
    offsets = np.frombuffer(blobs.buffers()[1], np.int32, count=len(blobs) + 1, offset=4 * blobs.offset)
    data = blobs.buffers()[2]
    data = np.frombuffer(data, np.uint8) if data is not None else np.empty(0, np.uint8)
    out = np.empty((len(blobs), *size), np.uint8)
    per_row = int(np.prod(lead[1:]))
    for j in range(len(blobs)):
        try:
            decode_mask_into(data[offsets[j]:offsets[j + 1]], out[j])
        except ValueError as exc:
            raise DatasetError(f"{source}: column {name!r}: row {j // per_row} view {j % per_row}: {exc}") from None
    return out.reshape(*lead, *size)


def _read_shard(
    path: Path, columns: Sequence[str], reference: dict | None, reference_path: Path | None = None
) -> tuple[dict, dict]:
    """(metadata, {column: array}) of one shard, validated (against ``reference``, the metadata of
    ``reference_path``, when given)."""
    source = str(path)
    pf = _open(path)
    meta = _metadata_from_schema(pf.schema_arrow, source)
    if reference is not None:
        for key in ("format_version", "cameras", "n_points", "joint_names", "config"):
            if meta.get(key) != reference.get(key):
                first = f"the split's first shard {reference_path}" if reference_path else "the split's first shard"
                raise DatasetError(f"{source}: metadata field {key!r} differs from {first} (one of them is damaged or foreign)")
    _check_schema(pf.schema_arrow, meta, source)
    cams = meta["cameras"]
    shapes = column_shapes(len(cams), int(cams[0]["height"]), int(cams[0]["width"]), int(meta["n_points"]))
    try:
        table = pf.read(columns=list(columns))
    except _READ_ERRORS as exc:  # a failed page checksum is an OSError
        raise DatasetError(f"{source}: cannot read data, the file is damaged ({_first_line(exc)})") from None
    arrays: dict = {}
    for name in columns:
        col = table.column(name)
        if col.null_count:
            raise DatasetError(f"{source}: column {name!r} has {col.null_count} null value(s)")
        if name in ("subject", "gait"):
            struct = col.combine_chunks()
            arrays[name] = {
                struct.type.field(j).name: struct.field(j).to_numpy(zero_copy_only=False)
                for j in range(struct.type.num_fields)
            }
        else:
            arrays[name] = _to_numpy(col, name, shapes.get(name), source)
        if name in FINITE_COLUMNS and not np.all(np.isfinite(arrays[name])):
            row = int(np.flatnonzero(~np.isfinite(arrays[name].reshape(len(table), -1)).all(1))[0])
            raise DatasetError(f"{source}: column {name!r} contains NaN or infinity (row {row})")
    return meta, arrays


def _columns(columns: Sequence[str] | None, with_masks: bool) -> list[str]:
    cols = list(DEFAULT_COLUMNS if columns is None else columns)
    unknown = [c for c in cols if c not in ALL_COLUMNS]
    if unknown:
        raise DatasetError(f"columns: unknown column(s) {unknown}; known: {list(ALL_COLUMNS)}")
    if with_masks and "masks" not in cols:
        cols.append("masks")
    if "sample_id" not in cols:
        cols.insert(0, "sample_id")
    return cols


def _assemble(parts: list[dict], meta: dict, files: list[Path], columns: list[str]) -> DatasetSplit:
    def cat(name):
        if name not in columns:
            return None
        arrs = [p[name] for p in parts]
        return arrs[0] if len(arrs) == 1 else np.concatenate(arrs)

    def cat_dict(name):
        if name not in columns:
            return {}
        return {k: (np.concatenate([p[name][k] for p in parts]) if len(parts) > 1 else parts[0][name][k])
                for k in parts[0][name]}

    extra_names = [c for c in ("split", "seed", "redraws", "contour_length", "area", "n_blobs") if c in columns]
    return DatasetSplit(
        sample_id=cat("sample_id"),
        joints=cat("joints"),
        contours=cat("contours"),
        centroid=cat("contour_centroid"),
        scale=cat("contour_scale"),
        touches_border=cat("touches_border"),
        masks=cat("masks"),
        subject=cat_dict("subject"),
        gait=cat_dict("gait"),
        rig=rig_from_metadata(meta),
        metadata=meta,
        files=list(files),
        extra={c: cat(c) for c in extra_names},
    )


def read_shard(path: str | Path, columns: Sequence[str] | None = None, with_masks: bool = False) -> DatasetSplit:
    """One shard file as a DatasetSplit (validated like ``load_split``)."""
    path = Path(path)
    cols = _columns(columns, with_masks)
    meta, arrays = _read_shard(path, cols, None)
    return _assemble([arrays], meta, [path], cols)


def iter_shards(
    root: str | Path, split: str, columns: Sequence[str] | None = None, with_masks: bool = False
) -> Iterator[tuple[Path, DatasetSplit]]:
    """Yield ``(path, DatasetSplit)`` one shard at a time (streaming; arrays of one shard only)."""
    cols = _columns(columns, with_masks)
    files = list_shards(root, split)
    if not files:
        raise DatasetError(f"{root}: no shards for split {split!r} ({shard_name(split, 0, 1)} ...)")
    reference = None
    for path in files:
        meta, arrays = _read_shard(path, cols, reference, files[0])
        reference = reference or meta
        yield path, _assemble([arrays], meta, [path], cols)


def load_split(
    root: str | Path, split: str, columns: Sequence[str] | None = None, with_masks: bool = False
) -> DatasetSplit:
    """Load one split of the dataset in ``root`` as numpy arrays (see ``DatasetSplit``).

    Args:
        root: the dataset folder.
        split: ``"train"`` or ``"test"`` (any split name present).
        columns: columns to read (default: all but ``masks``); ``sample_id`` is always read.
        with_masks: also read ``masks`` (N, K, H, W) uint8 — 300 KiB per sample in memory at 4 x 320x240.
    Raises:
        DatasetError naming the file and the field: missing or foreign or truncated shard, schema or
        metadata mismatch, NaN, duplicate sample ids.
    """
    cols = _columns(columns, with_masks)
    parts, files, meta = [], [], None
    for path, shard in iter_shards(root, split, cols, with_masks):
        meta = meta or shard.metadata
        for name in ("subject", "gait"):
            if name in cols and parts and list(getattr(shard, name)) != list(parts[0][name]):
                raise DatasetError(
                    f"{path}: column {name!r} has fields {list(getattr(shard, name))}, the split's first shard "
                    f"{files[0]} has {list(parts[0][name])}"
                )
        files.append(path)
        parts.append(_shard_arrays(shard, cols))
    result = _assemble(parts, meta, files, cols)
    ids, counts = np.unique(result.sample_id, return_counts=True)
    if np.any(counts > 1):
        raise DatasetError(f"{root}: split {split!r} column 'sample_id': duplicate id(s) {ids[counts > 1][:5].tolist()}")
    return result


def _shard_arrays(shard: DatasetSplit, cols: list[str]) -> dict:
    named = {
        "sample_id": shard.sample_id,
        "joints": shard.joints,
        "contours": shard.contours,
        "contour_centroid": shard.centroid,
        "contour_scale": shard.scale,
        "touches_border": shard.touches_border,
        "masks": shard.masks,
        "subject": shard.subject,
        "gait": shard.gait,
        **shard.extra,
    }
    return {c: named[c] for c in cols}


def expected_shapes(metadata: dict) -> dict[str, tuple[int, ...]]:
    """Per-row shape of every per-view column for ``metadata`` (K views, H x W, n points)."""
    cams = metadata["cameras"]
    return column_shapes(len(cams), int(cams[0]["height"]), int(cams[0]["width"]), int(metadata["n_points"]))
