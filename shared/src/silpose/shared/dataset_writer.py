"""Write silpose dataset shards: records -> Arrow table (format version 2) -> Parquet (zstd), atomically."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .atomic import atomic_path
from .dataset_schema import (
    FORMAT_VERSION,
    MASK_IMAGE_TYPE,
    SCALAR_COLUMNS,
    TENSOR_COLUMNS,
    TENSOR_DTYPES,
    DatasetError,
    build_schema,
    check_metadata,
    column_shapes,
)
from .mask_png import encode_mask


def write_shard(path: str | Path, records: list[dict], metadata: dict) -> None:
    """Write ``records`` as one Parquet shard (zstd), atomically (:func:`silpose.shared.atomic.atomic_path`).

    Every data page carries a CRC32 (``write_page_checksum``), which the readers verify, so a
    flipped byte in the data is an error instead of silently different values.

    Args:
        path: the shard's final path.
        records: dicts with the keys of the schema (see ``dataset_schema``); per record
            ``joints`` (19, 3) metres, ``masks`` (K, H, W) uint8 0/1, ``contours`` (K, n, 2) px,
            ``contour_centroid`` (K, 2) px, ``contour_scale`` (K,) px, ``contour_length`` (K,) px,
            ``area`` (K,), ``n_blobs`` (K,), ``touches_border`` (K,) bool, ``subject`` / ``gait``
            dicts of floats with the same keys in every record.
        metadata: the ``silpose`` document (``build_metadata``); K, H, W and n come from it. Shards
            are written in format ``FORMAT_VERSION`` only (masks as 1-bit PNG images).
    """
    path = Path(path)
    check_metadata(metadata, str(path))
    if not records:
        raise DatasetError(f"{path}: no records to write")
    _write_table(records_to_table(records, metadata, source=str(path)), path)


def restamp_shard(path: str | Path, metadata: dict) -> None:
    """Rewrite the shard ``path`` with the ``silpose`` metadata document ``metadata``, its rows unchanged
    (atomically, written as :func:`write_shard` writes). For metadata fields the rows do not depend on
    (``silpose gen``'s resume: ``silpose.datagen.shards.RESUME_NEUTRAL``).

    The rows are cast to the schema :func:`write_shard` would build for ``metadata``, so the file is byte for
    byte the one a fresh generation writes. (A table read back from Parquet equals that schema but names its
    list items differently, and the footer's Arrow schema, and the file's checksum, then differed.)"""
    path = Path(path)
    check_metadata(metadata, str(path))
    table = pq.read_table(path)
    names = {col: [f.name for f in table.schema.field(col).type] for col in ("subject", "gait")}
    _write_table(table.cast(build_schema(metadata, names["subject"], names["gait"])), path)


def _write_table(table: pa.Table, path: Path) -> None:
    """Write a shard's ``table`` to ``path`` atomically: zstd, one row group, a CRC32 on every page."""
    leaves = parquet_leaves(table.schema)
    with atomic_path(path, mkdir=False) as tmp:
        pq.write_table(
            table, tmp, compression="zstd", row_group_size=max(1, table.num_rows), write_page_checksum=True,
            use_byte_stream_split=[p for p, typ in leaves if pa.types.is_floating(typ)],
            use_dictionary=[p for p, typ in leaves if not pa.types.is_floating(typ) and not p.startswith("masks.")],
        )


def parquet_leaves(schema: pa.Schema) -> list[tuple[str, pa.DataType]]:
    """``(Parquet column path, Arrow leaf type)`` of every leaf column of ``schema``, e.g.
    ``("contours.list.element.list.element.list.element", float32)``, ``("subject.height", float32)``.

    Floats are written with BYTE_STREAM_SPLIT (43 % smaller contours than dictionary/plain and
    faster to decode); PNG masks without a dictionary (every file is unique).
    """
    out = []

    def walk(path: str, typ: pa.DataType) -> None:
        if pa.types.is_struct(typ):
            for j in range(typ.num_fields):
                walk(f"{path}.{typ.field(j).name}", typ.field(j).type)
        elif pa.types.is_fixed_size_list(typ) or pa.types.is_list(typ):
            walk(f"{path}.list.element", typ.value_type)
        elif isinstance(typ, pa.ExtensionType):
            walk(path, typ.storage_type)
        else:
            out.append((path, typ))

    for field in schema:
        walk(field.name, field.type)
    return out


def records_to_table(records: list[dict], metadata: dict, source: str = "records") -> pa.Table:
    """Arrow table of ``records`` (see ``write_shard``) in format ``FORMAT_VERSION``, shapes checked
    against ``metadata``."""
    if metadata["format_version"] != FORMAT_VERSION:
        raise DatasetError(
            f"{source}: metadata field 'format_version' is {metadata['format_version']!r}; "
            f"silpose writes version {FORMAT_VERSION} only"
        )
    cams = metadata["cameras"]
    K, H, W, n = len(cams), int(cams[0]["height"]), int(cams[0]["width"]), int(metadata["n_points"])
    subject_fields = list(records[0].get("subject", {}))
    gait_fields = list(records[0].get("gait", {}))
    schema = build_schema(metadata, subject_fields, gait_fields)
    shapes = column_shapes(K, H, W, n)
    arrays = {}
    for col, typ in SCALAR_COLUMNS.items():
        values = [_field(r, col, source, i) for i, r in enumerate(records)]
        arrays[col] = pa.array(values, type=typ)
    for col, names in (("subject", subject_fields), ("gait", gait_fields)):
        cols = {}
        for name in names:
            vals = np.empty(len(records), np.float32)
            for i, r in enumerate(records):
                d = _field(r, col, source, i)
                if list(d) != names:
                    raise DatasetError(f"{source}: record {i} field {col}: keys {list(d)} differ from {names}")
                vals[i] = d[name]
            cols[name] = pa.array(vals)
        arrays[col] = pa.StructArray.from_arrays(list(cols.values()), names=names) if names else pa.array(
            [{}] * len(records), type=pa.struct([])
        )
    for col in TENSOR_COLUMNS + ("touches_border",):
        dtype = bool if col == "touches_border" else TENSOR_DTYPES[col]
        stacked = np.empty((len(records),) + shapes[col], dtype=dtype)
        for i, r in enumerate(records):
            value = np.asarray(_field(r, col, source, i))
            if value.shape != shapes[col]:
                raise DatasetError(f"{source}: record {i} field {col}: expected shape {shapes[col]}, got {value.shape}")
            stacked[i] = value
        if col in ("joints", "contours", "contour_centroid", "contour_scale") and not np.all(np.isfinite(stacked)):
            bad = int(np.flatnonzero(~np.isfinite(stacked.reshape(len(records), -1)).all(1))[0])
            raise DatasetError(f"{source}: record {bad} field {col}: contains NaN or infinity")
        if col == "masks":
            arrays[col] = _mask_images(stacked, source)
        else:
            arrays[col] = nested_lists(stacked)
    return pa.Table.from_arrays([arrays[f.name] for f in schema], schema=schema)


def nested_lists(array: np.ndarray) -> pa.FixedSizeListArray:
    """(N, d1, ..., dk) numpy array -> length-N Arrow array of ``list<...list<T>[dk]...>[d1]``."""
    out = pa.array(array.ravel())
    for size in reversed(array.shape[1:]):
        out = pa.FixedSizeListArray.from_arrays(out, int(size))
    return out


def _mask_images(masks: np.ndarray, source: str) -> pa.FixedSizeListArray:
    """(N, K, H, W) 0/1 masks -> ``list<struct<bytes, path>>[K]``, one 1-bit PNG per view."""
    n, k = masks.shape[:2]
    blobs = []
    for i in range(n):
        for v in range(k):
            try:
                blobs.append(encode_mask(masks[i, v]))
            except ValueError as exc:
                raise DatasetError(f"{source}: record {i} field masks: view {v}: {exc}") from None
    images = pa.StructArray.from_arrays(
        [pa.array(blobs, pa.binary()), pa.nulls(n * k, pa.string())], fields=list(MASK_IMAGE_TYPE)
    )
    return pa.FixedSizeListArray.from_arrays(images, k)


def _field(record: dict, name: str, source: str, i: int):
    try:
        return record[name]
    except KeyError:
        raise DatasetError(f"{source}: record {i} lacks field {name}") from None
