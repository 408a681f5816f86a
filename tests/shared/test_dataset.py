"""silpose.shared.dataset: Parquet round trip, independent pyarrow reads, validation errors."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from silpose.shared.camera import default_rig
from silpose.shared.dataset import (
    DatasetError,
    build_metadata,
    iter_shards,
    list_shards,
    load_split,
    read_metadata,
    read_shard,
    shard_name,
    write_shard,
)

K, H, W, NPTS = 4, 240, 320, 16


@pytest.fixture
def metadata() -> dict:
    return build_metadata(default_rig().to_dict()["cameras"], {"name": "unit", "seed": 3}, NPTS)


def synthetic_records(n: int, start: int = 0, seed: int = 0, split: str = "train") -> list[dict]:
    """Test fixture: random records with the schema's fields and shapes (not a rendering)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(start, start + n):
        masks = (rng.random((K, H, W)) < 0.1).astype(np.uint8)
        out.append({
            "sample_id": i, "split": split, "seed": 3, "redraws": int(rng.integers(0, 4)),
            "subject": {"height": float(rng.uniform(1.5, 1.9)), "g_torso": float(rng.uniform())},
            "gait": {"phase": float(rng.uniform()), "stride": float(rng.uniform()), "heading": float(rng.normal())},
            "joints": rng.normal(size=(19, 3)).astype(np.float32),
            "masks": masks,
            "contours": rng.uniform(0, 300, size=(K, NPTS, 2)).astype(np.float32),
            "contour_centroid": rng.uniform(0, 300, size=(K, 2)).astype(np.float32),
            "contour_scale": rng.uniform(10, 40, size=K).astype(np.float32),
            "touches_border": rng.random(K) < 0.5,
            "n_blobs": rng.integers(1, 3, size=K).astype(np.int32),
            "contour_length": rng.uniform(200, 500, size=K).astype(np.float32),
            "area": masks.reshape(K, -1).sum(1).astype(np.int32),
        })
    return out


def _stack(records, key):
    return np.stack([np.asarray(r[key]) for r in records])


def test_round_trip_values_types_and_metadata(tmp_path, metadata):
    recs = synthetic_records(5)
    path = tmp_path / shard_name("train", 0, 1)
    write_shard(path, recs, metadata)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary left behind
    schema = pq.read_schema(path)
    masks_type = schema.field("masks").type  # K images, Hugging Face's Image storage
    assert pa.types.is_fixed_size_list(masks_type) and masks_type.list_size == K
    assert masks_type.value_type == pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    contours_type = schema.field("contours").type  # (K, n, 2) as nested fixed-size lists
    assert [contours_type.list_size, contours_type.value_type.list_size, contours_type.value_type.value_type.list_size] \
        == [K, NPTS, 2]
    assert contours_type.value_type.value_type.value_type == pa.float32()
    assert pq.ParquetFile(path).metadata.row_group(0).column(0).compression == "ZSTD"
    rg = pq.ParquetFile(path).metadata.row_group(0)
    encodings = {rg.column(j).path_in_schema: rg.column(j).encodings for j in range(rg.num_columns)}
    assert "BYTE_STREAM_SPLIT" in encodings["contours.list.element.list.element.list.element"]
    assert "BYTE_STREAM_SPLIT" in encodings["joints.list.element.list.element"]
    assert "BYTE_STREAM_SPLIT" in encodings["gait.stride"]
    assert "RLE_DICTIONARY" not in encodings["masks.list.element.bytes"]
    assert "RLE_DICTIONARY" in encodings["split"]
    assert read_metadata(path) == json.loads(json.dumps(metadata))
    s = read_shard(path, with_masks=True)
    np.testing.assert_array_equal(s.sample_id, np.arange(5))
    np.testing.assert_array_equal(s.joints, _stack(recs, "joints"))
    np.testing.assert_array_equal(s.masks, _stack(recs, "masks"))
    np.testing.assert_array_equal(s.contours, _stack(recs, "contours"))
    np.testing.assert_array_equal(s.centroid, _stack(recs, "contour_centroid"))
    np.testing.assert_array_equal(s.scale, _stack(recs, "contour_scale"))
    np.testing.assert_array_equal(s.touches_border, _stack(recs, "touches_border"))
    np.testing.assert_array_equal(s.extra["area"], _stack(recs, "area"))
    np.testing.assert_array_equal(s.extra["redraws"], [r["redraws"] for r in recs])
    np.testing.assert_array_equal(s.subject["height"], np.float32([r["subject"]["height"] for r in recs]))
    assert list(s.gait) == ["phase", "stride", "heading"]
    assert s.joints.dtype == np.float32 and s.masks.dtype == np.uint8 and s.touches_border.dtype == bool
    assert s.n_views == K and s.rig.names == default_rig().names
    np.testing.assert_allclose(s.rig[1].K, default_rig()[1].K)


def test_independent_pyarrow_read_matches(tmp_path, metadata):
    """Plain pyarrow and OpenCV (no silpose reader): flattened lists and decoded PNGs give the written arrays."""
    recs = synthetic_records(3)
    path = tmp_path / shard_name("test", 0, 1)
    write_shard(path, recs, metadata)
    table = pq.read_table(path)
    flat = table.column("contours").combine_chunks().flatten().flatten().flatten().to_numpy()
    np.testing.assert_array_equal(flat.reshape(3, K, NPTS, 2), _stack(recs, "contours"))
    for i, views in enumerate(table.column("masks").to_pylist()):
        assert [v["path"] for v in views] == [None] * K
        png = views[1]["bytes"]
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and png[24:26] == bytes([1, 0])  # IHDR: bit depth 1, greyscale
        decoded = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
        np.testing.assert_array_equal(decoded // 255, recs[i]["masks"][1])
    assert table.column("gait").combine_chunks().field("stride").to_pylist() == pytest.approx(
        [r["gait"]["stride"] for r in recs], rel=1e-6
    )
    assert table.column("split").to_pylist() == ["train"] * 3


def test_reads_are_zero_copy_per_chunk(tmp_path, metadata):
    path = tmp_path / shard_name("train", 0, 1)
    write_shard(path, synthetic_records(4), metadata)
    table = pq.read_table(path, columns=["joints"])
    leaf = table.column("joints").chunk(0).flatten().flatten()
    arr = leaf.to_numpy()
    assert arr.ctypes.data == leaf.buffers()[1].address + leaf.offset * 4  # pyarrow's own view
    s = read_shard(path, columns=["joints", "contours"])
    assert not s.joints.flags.owndata and not s.contours.flags.owndata  # views on Arrow memory


def test_load_split_concatenates_shards_in_order_and_streams(tmp_path, metadata):
    recs = synthetic_records(7)
    for i, (a, b) in enumerate([(0, 3), (3, 6), (6, 7)]):
        write_shard(tmp_path / shard_name("train", i, 3), recs[a:b], metadata)
    write_shard(tmp_path / shard_name("test", 0, 1), synthetic_records(2, split="test", seed=1), metadata)
    s = load_split(tmp_path, "train")
    assert len(s) == 7 and s.masks is None and [f.name for f in s.files] == [shard_name("train", i, 3) for i in range(3)]
    np.testing.assert_array_equal(s.joints, _stack(recs, "joints"))
    assert [len(part) for _, part in iter_shards(tmp_path, "train")] == [3, 3, 1]
    assert len(load_split(tmp_path, "test")) == 2
    sub = load_split(tmp_path, "train", columns=["joints"])
    assert sub.contours is None and sub.subject == {} and sub.joints.shape == (7, 19, 3)


def test_write_rejects_bad_records_and_leaves_nothing(tmp_path, metadata):
    path = tmp_path / shard_name("train", 0, 1)
    recs = synthetic_records(3)
    recs[2]["contours"] = recs[2]["contours"][:, :-1]
    with pytest.raises(DatasetError, match=r"record 2 field contours: expected shape \(4, 16, 2\)"):
        write_shard(path, recs, metadata)
    recs = synthetic_records(3)
    recs[1]["joints"][4, 0] = np.nan
    with pytest.raises(DatasetError, match="record 1 field joints: contains NaN"):
        write_shard(path, recs, metadata)
    recs = synthetic_records(2)
    del recs[1]["masks"]
    with pytest.raises(DatasetError, match="record 1 lacks field masks"):
        write_shard(path, recs, metadata)
    assert list(tmp_path.iterdir()) == []


def test_foreign_and_truncated_files_give_one_line_errors(tmp_path, metadata):
    foreign = tmp_path / shard_name("train", 0, 1)
    pq.write_table(pa.table({"x": [1, 2, 3]}), foreign)
    with pytest.raises(DatasetError) as err:
        load_split(tmp_path, "train")
    assert str(foreign) in str(err.value) and "'silpose'" in str(err.value) and "\n" not in str(err.value)

    good = tmp_path / "g" / shard_name("train", 0, 1)
    good.parent.mkdir()
    write_shard(good, synthetic_records(2), metadata)
    data = good.read_bytes()
    good.write_bytes(data[: len(data) // 2])
    with pytest.raises(DatasetError) as err:
        read_metadata(good)
    assert str(good) in str(err.value) and "not a readable Parquet file" in str(err.value)
    assert "\n" not in str(err.value)


def test_metadata_validation_names_the_field(tmp_path, metadata):
    path = tmp_path / shard_name("train", 0, 1)
    bad = dict(metadata, format_version=99)
    with pytest.raises(DatasetError, match="format_version"):
        write_shard(path, synthetic_records(1), bad)
    table = pq.read_table(_write(tmp_path / "ok", metadata))
    for key, value, pattern in [("format_version", 99, "'format_version': unknown version 99"),
                                ("joint_names", ["a"] * 19, "'joint_names'"),
                                ("cameras", None, "field 'cameras' missing")]:
        meta = dict(metadata)
        if value is None:
            del meta[key]
        else:
            meta[key] = value
        p = tmp_path / f"{key}.parquet"
        pq.write_table(table.replace_schema_metadata({b"silpose": json.dumps(meta).encode()}), p)
        with pytest.raises(DatasetError, match=pattern) as err:
            read_metadata(p)
        assert str(p) in str(err.value)


def _write(folder, metadata, n=2, **kw):
    folder.mkdir(exist_ok=True)
    path = folder / shard_name("train", 0, 1)
    write_shard(path, synthetic_records(n, **kw), metadata)
    return path


def test_load_split_detects_nan_duplicates_gaps_and_mixed_metadata(tmp_path, metadata):
    # NaN written behind the writer's back, through plain pyarrow
    path = _write(tmp_path / "nan", metadata)
    table = pq.read_table(path)
    j = table.column("joints").combine_chunks().flatten().flatten().to_numpy().copy()
    j[1 * 57 + 2 * 3 + 1] = np.nan  # row 1, joint 2, y
    col = pa.FixedSizeListArray.from_arrays(pa.FixedSizeListArray.from_arrays(pa.array(j), 3), 19)
    pq.write_table(table.set_column(table.schema.get_field_index("joints"), table.schema.field("joints"), col), path)
    with pytest.raises(DatasetError, match=r"column 'joints' contains NaN or infinity \(row 1\)") as err:
        load_split(path.parent, "train")
    assert str(path) in str(err.value)

    dup = tmp_path / "dup"
    dup.mkdir()
    write_shard(dup / shard_name("train", 0, 2), synthetic_records(2), metadata)
    write_shard(dup / shard_name("train", 1, 2), synthetic_records(2, start=1), metadata)
    with pytest.raises(DatasetError, match=r"'sample_id': duplicate id\(s\) \[1\]"):
        load_split(dup, "train")

    gap = tmp_path / "gap"
    gap.mkdir()
    write_shard(gap / shard_name("train", 1, 2), synthetic_records(2), metadata)
    with pytest.raises(DatasetError, match="lacks shard"):
        list_shards(gap, "train")

    mixed = tmp_path / "mixed"
    mixed.mkdir()
    write_shard(mixed / shard_name("train", 0, 2), synthetic_records(2), metadata)
    write_shard(mixed / shard_name("train", 1, 2), synthetic_records(2, start=2), dict(metadata, config={"seed": 4}))
    with pytest.raises(DatasetError, match="'config' differs from the split's first shard") as err:
        load_split(mixed, "train")
    assert shard_name("train", 1, 2) in str(err.value)


def test_no_shards_is_an_error(tmp_path):
    with pytest.raises(DatasetError, match="no shards for split 'train'"):
        load_split(tmp_path, "train")
    with pytest.raises(DatasetError, match="dataset folder not found"):
        load_split(tmp_path / "missing", "train")


# ----------------------------------------------------------------------------- format versions, PNG masks


def test_version_1_shards_are_still_read(tmp_path, metadata, write_v1_shard):
    """The previous layout (fixed_shape_tensor columns, raw uint8 masks) reads to the same arrays."""
    recs = synthetic_records(4)
    write_v1_shard(tmp_path / shard_name("train", 0, 1), recs, metadata)
    assert isinstance(pq.read_schema(tmp_path / shard_name("train", 0, 1)).field("masks").type, pa.FixedShapeTensorType)
    s = load_split(tmp_path, "train", with_masks=True)
    assert s.metadata["format_version"] == 1
    for name, key in [("joints", "joints"), ("masks", "masks"), ("contours", "contours"), ("centroid", "contour_centroid"),
                      ("scale", "contour_scale"), ("touches_border", "touches_border")]:
        np.testing.assert_array_equal(getattr(s, name), _stack(recs, key), err_msg=name)
    np.testing.assert_array_equal(s.extra["n_blobs"], _stack(recs, "n_blobs"))


def test_mixed_format_versions_in_one_split_are_refused(tmp_path, metadata, write_v1_shard):
    write_v1_shard(tmp_path / shard_name("train", 0, 2), synthetic_records(2), metadata)
    write_shard(tmp_path / shard_name("train", 1, 2), synthetic_records(2, start=2), metadata)
    with pytest.raises(DatasetError, match="'format_version' differs from the split's first shard") as err:
        load_split(tmp_path, "train")
    assert shard_name("train", 1, 2) in str(err.value)


def test_writer_writes_the_current_version_only_and_binary_masks_only(tmp_path, metadata):
    path = tmp_path / shard_name("train", 0, 1)
    with pytest.raises(DatasetError, match="'format_version' is 1; silpose writes version 2 only"):
        write_shard(path, synthetic_records(1), dict(metadata, format_version=1))
    recs = synthetic_records(2)
    recs[1]["masks"][3, 5, 7] = 2  # a 1-bit PNG cannot hold it: refuse instead of losing it
    with pytest.raises(DatasetError, match="record 1 field masks: view 3: a mask must hold only 0 and 1"):
        write_shard(path, recs, metadata)
    assert list(tmp_path.iterdir()) == []


def test_damaged_mask_image_names_file_row_and_view(tmp_path, metadata):
    path = _write(tmp_path / "png", metadata, n=3)
    table = pq.read_table(path)
    rows = table.column("masks").to_pylist()
    rows[2][1]["bytes"] = rows[2][1]["bytes"][:40]  # truncated PNG
    col = pa.array(rows, type=table.schema.field("masks").type)
    pq.write_table(table.set_column(table.schema.get_field_index("masks"), table.schema.field("masks"), col), path)
    with pytest.raises(DatasetError, match=r"column 'masks': row 2 view 1: not a readable PNG image") as err:
        read_shard(path, with_masks=True)
    assert str(path) in str(err.value) and "\n" not in str(err.value)
    assert read_shard(path).joints.shape == (3, 19, 3)  # the other columns do not decode images


def test_null_inside_a_nested_list_is_an_error(tmp_path, metadata):
    path = _write(tmp_path / "null", metadata, n=2)
    table = pq.read_table(path)
    area = table.column("area").combine_chunks().flatten().to_pylist()
    area[5] = None
    col = pa.FixedSizeListArray.from_arrays(pa.array(area, pa.int32()), K)
    pq.write_table(table.set_column(table.schema.get_field_index("area"), table.schema.field("area"), col), path)
    with pytest.raises(DatasetError, match=r"column 'area' has 1 null value\(s\) inside its lists"):
        read_shard(path)


def test_hugging_face_features_in_the_schema_match_its_columns(tmp_path, metadata):
    """``datasets`` reads the ``huggingface`` key: every declared feature applies (types equal), and
    masks are a list of K images."""
    datasets = pytest.importorskip("datasets")
    path = _write(tmp_path / "hf", metadata)
    schema = pq.read_schema(path)
    declared = datasets.Features.from_dict(json.loads(schema.metadata[b"huggingface"])["info"]["features"])
    assert datasets.Features.from_arrow_schema(schema) == declared
    assert list(declared) == schema.names
    assert declared["masks"] == datasets.List(datasets.Image(), length=K)
    assert declared["contours"] == datasets.List(datasets.List(datasets.List(datasets.Value("float32"), length=2),
                                                               length=NPTS), length=K)
    assert declared.arrow_schema.remove_metadata().equals(schema.remove_metadata())
