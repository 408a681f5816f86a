"""Drill: a corrupted (bytes flipped) or truncated shard.

``silpose validate`` and every reader -- ``load_split``, ``iter_shards``, ``read_shard``,
``silpose train``, ``silpose infer`` on a dataset, ``silpose eval`` -- must fail with one clear
error that names the damaged file, never a traceback and never silently different numbers.
Shards carry per-page CRC32 checksums (``write_shard``) that the readers verify.
"""

from __future__ import annotations

import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from silpose.model.persistence import save_model
from silpose.app.training import fit_dataset
from silpose.model.shape_model import ShapeStructureModel
from silpose.shared.cli import build_app
from silpose.shared.dataset import DatasetError, iter_shards, load_split, read_shard

TRAIN0 = "train-00000-of-00002.parquet"
TEST0 = "test-00000-of-00001.parquet"


def _column_middle(path, column: str) -> int:
    """Byte offset of the middle of ``column``'s (compressed) data in the first row group."""
    rg = pq.ParquetFile(path).metadata.row_group(0)
    for j in range(rg.num_columns):
        c = rg.column(j)
        if c.path_in_schema.split(".")[0] == column:
            start = c.dictionary_page_offset if c.has_dictionary_page else c.data_page_offset
            return int(start + c.total_compressed_size // 2)
    raise KeyError(column)


def _flip(data: bytes, offset: int, n: int = 8) -> bytes:
    b = bytearray(data)
    for i in range(offset, offset + n):
        b[i] ^= 0xA5
    return bytes(b)


def corrupt(path, how: str) -> None:
    """Damage one shard in place."""
    data = path.read_bytes()
    if how == "truncated_half":
        out = data[: len(data) // 2]
    elif how == "truncated_footer":
        out = data[:-100]
    elif how == "flipped_contours":  # inside the zstd-compressed page of a column every reader reads
        out = _flip(data, _column_middle(path, "contours"))
    elif how == "flipped_joints":
        out = _flip(data, _column_middle(path, "joints"), 4)
    elif how == "flipped_footer_length":  # the 4-byte footer length before the trailing magic
        out = _flip(data, len(data) - 8, 4)
    elif how == "zeroed_block":  # a lost disk block in the middle of the file
        mid = len(data) // 2
        out = data[:mid] + bytes(4096) + data[mid + 4096 :]
    else:  # pragma: no cover
        raise ValueError(how)
    assert out != data
    path.write_bytes(out)


CORRUPTIONS = ["truncated_half", "truncated_footer", "flipped_contours", "flipped_joints", "flipped_footer_length",
               "zeroed_block"]


@pytest.fixture(scope="module")
def model_file(clean_dataset, tmp_path_factory):
    """A small model fitted on the clean dataset (for ``silpose infer`` and ``silpose eval``)."""
    root, _ = clean_dataset
    model = fit_dataset(ShapeStructureModel(1, 2, n_init=1, max_iter=5), load_split(root, "train"))
    return save_model(tmp_path_factory.mktemp("drill-model") / "tiny.npz", model)


def damaged_copy(clean_dataset, tmp_path, shard: str, how: str):
    root, _ = clean_dataset
    copy = tmp_path / "ds"
    shutil.copytree(root, copy)
    corrupt(copy / shard, how)
    return copy, copy / shard


def _cli(*args):
    return CliRunner().invoke(build_app(), [str(a) for a in args])


def _assert_clear_failure(result, path) -> None:
    """A non-zero exit, the damaged file named, no traceback."""
    text = result.output + (result.stderr if result.stderr_bytes is not None else "")
    assert result.exit_code != 0, text
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert str(path) in text, text
    assert "Traceback" not in text, text


@pytest.mark.parametrize("how", CORRUPTIONS)
def test_every_library_reader_names_the_damaged_shard(clean_dataset, tmp_path, how):
    root, bad = damaged_copy(clean_dataset, tmp_path, TRAIN0, how)
    readers = {
        "load_split": lambda: load_split(root, "train"),
        "load_split_masks": lambda: load_split(root, "train", with_masks=True),
        "load_split_train_columns": lambda: load_split(root, "train", columns=["joints", "contours"]),
        "iter_shards": lambda: [s for _, s in iter_shards(root, "train", with_masks=True)],
        "read_shard": lambda: read_shard(bad, with_masks=True),
    }
    for name, read in readers.items():
        with pytest.raises(DatasetError) as err:
            read()
        assert str(bad) in str(err.value), (name, str(err.value))
        assert "\n" not in str(err.value), name  # one line


@pytest.mark.parametrize("how", CORRUPTIONS)
def test_validate_names_the_damaged_shard(clean_dataset, tmp_path, how):
    root, bad = damaged_copy(clean_dataset, tmp_path, TRAIN0, how)
    r = _cli("validate", root)
    assert r.exit_code == 1 and str(bad) in r.output and "FAILED" in r.output, r.output
    r = _cli("validate", bad)
    _assert_clear_failure(r, bad)


@pytest.mark.parametrize("how", ["truncated_half", "flipped_contours", "flipped_footer_length"])
def test_train_infer_and_eval_name_the_damaged_shard(clean_dataset, model_file, tmp_path, how):
    root, bad = damaged_copy(clean_dataset, tmp_path, TRAIN0, how)
    out = tmp_path / "m.npz"
    r = _cli("train", root, "--out", out, "-M", "1", "-q", "2", "--n-init", "1", "--max-iter", "3", "--no-progress")
    _assert_clear_failure(r, bad)
    assert not out.exists() and not list(tmp_path.glob(".m.npz*"))

    shutil.rmtree(root)
    root, bad = damaged_copy(clean_dataset, tmp_path, TEST0, how)
    joints = tmp_path / "joints.parquet"
    r = _cli("infer", model_file, root, "--split", "test", "--out", joints)
    _assert_clear_failure(r, bad)
    assert not joints.exists()
    r = _cli("eval", root, "--model", model_file, "--out", tmp_path / "report", "--no-frames")
    _assert_clear_failure(r, bad)


# ------------------------------------------------------------------ any flipped byte


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(where=st.floats(0.0, 1.0, exclude_max=True), mask=st.integers(1, 255))
def test_any_flipped_byte_is_an_error_or_harmless(clean_dataset, tmp_path_factory, where, mask):
    """One byte anywhere in a shard XOR ``mask``: the readers raise DatasetError naming the file, or
    return exactly the original arrays (a flip in statistics, padding or an unread column) -- never
    other numbers and never another exception type."""
    root, _ = clean_dataset
    tmp = tmp_path_factory.mktemp("flip")
    copy = tmp / "ds"
    shutil.copytree(root, copy)
    path = copy / TRAIN0
    data = bytearray(path.read_bytes())
    pos = int(where * len(data))
    data[pos] ^= mask
    path.write_bytes(bytes(data))
    for kwargs in ({}, {"with_masks": True}):
        ref = load_split(root, "train", **kwargs)
        try:
            got = load_split(copy, "train", **kwargs)
        except DatasetError as exc:
            assert str(path) in str(exc), (pos, str(exc))
            continue
        for name in ("sample_id", "joints", "contours", "centroid", "scale", "touches_border", "masks"):
            a, b = getattr(ref, name), getattr(got, name)
            assert (a is None) == (b is None) and (a is None or np.array_equal(a, b)), (pos, name)
        for group in ("subject", "gait", "extra"):
            a, b = getattr(ref, group), getattr(got, group)
            assert list(a) == list(b), (pos, group)
            for k in a:
                assert np.array_equal(a[k], b[k]), (pos, group, k)
    shutil.rmtree(tmp)
