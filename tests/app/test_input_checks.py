"""``silpose train`` / ``silpose infer`` input checks of issue 13 (each failed before its fix):

- ``silpose train /no/such/dir`` says the folder does not exist (it said "no dataset folder for preset");
- ``silpose train`` checks the train shards against the manifest's sha256, as ``silpose validate``
  does (a shard with an edited footer trained silently);
- 0/1 silhouette PNGs (the dataset's own mask encoding) are read as masks by ``silpose infer`` (it said
  "no usable silhouette"), and an all-dark mask folder's error points at ``--threshold``.
"""

from __future__ import annotations

import cv2
import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from silpose.datagen.config import load_config
from silpose.datagen.pipeline import generate
from silpose.datagen.testing import SYNTH_RENDER, tiny_config_toml
from silpose.model.persistence import load_model
from silpose.shared.cli import build_app
from silpose.shared.dataset import load_split
from silpose.shared.metrics import chamfer_errors
from silpose.shared.skeleton import JOINT_NAMES


def silpose(*args):
    res = CliRunner().invoke(build_app(), [str(a) for a in args])
    return res.exit_code, res.output


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """A dataset written by the generation pipeline (stand-in renderer): its manifest hashes every shard."""
    tmp = tmp_path_factory.mktemp("generated")
    (tmp / "tiny.toml").write_text(tiny_config_toml(train=40, test=6, shard_size=20))
    generate(load_config(tmp / "tiny.toml"), tmp / "ds", workers=1, render=SYNTH_RENDER, progress=False)
    return tmp / "ds"


@pytest.fixture(scope="module")
def model(generated, tmp_path_factory):
    out = tmp_path_factory.mktemp("model") / "m.npz"
    code, output = silpose("train", generated, "--out", out, "-M", "2", "-q", "3", "--n-init", "1", "--max-iter", "20",
                           "--no-progress")
    assert code == 0, output
    return out


def test_train_names_a_missing_dataset_folder(tmp_path):
    code, output = silpose("train", tmp_path / "no" / "such" / "dir", "--out", tmp_path / "m.npz")
    assert code == 2
    assert f"{tmp_path / 'no' / 'such' / 'dir'}: no such dataset folder" in output and "preset" not in output
    (tmp_path / "file.txt").write_text("x")
    code, output = silpose("train", tmp_path / "file.txt", "--out", tmp_path / "m.npz")
    assert code == 2 and "file.txt: not a dataset folder" in output
    code, output = silpose("train", "no-such-preset", "--data-root", tmp_path)  # a name: still about the preset
    assert code == 2 and "no dataset folder for preset 'no-such-preset'" in output


def test_train_refuses_a_shard_whose_footer_was_edited(generated, tmp_path):
    import shutil

    ds = tmp_path / "ds"
    shutil.copytree(generated, ds)
    shard = ds / "train-00001-of-00002.parquet"
    raw = shard.read_bytes()
    assert raw.count(b"parquet-cpp-arrow") == 1
    shard.write_bytes(raw.replace(b"parquet-cpp-arrow", b"parquet-CPP-arrow"))  # the footer's created_by
    assert pq.read_metadata(shard).created_by.startswith("parquet-CPP-arrow")  # still a readable shard
    assert len(load_split(ds, "train")) == 40  # every reader accepts it ...
    code, output = silpose("validate", ds)
    assert code == 1 and "sha256 differs" in output  # ... validate catches it ...
    out = tmp_path / "m.npz"
    code, output = silpose("train", ds, "--out", out, "-M", "2", "-q", "3", "--n-init", "1", "--no-progress")
    assert code == 2 and f"{shard}: sha256 differs from" in output  # ... and so does train, before fitting
    assert not out.exists()
    for streaming in ("--streaming",):
        code, output = silpose("train", ds, "--out", out, "-M", "2", "-q", "3", "--n-init", "1", "--no-progress", streaming)
        assert code == 2 and "sha256 differs" in output


def test_train_refuses_a_shard_not_in_the_manifest(generated, tmp_path):
    import shutil

    ds = tmp_path / "ds"
    shutil.copytree(generated, ds)
    (ds / "train-00001-of-00002.parquet").rename(ds / "train-00000-of-00001.parquet")
    (ds / "train-00000-of-00002.parquet").unlink()
    code, output = silpose("train", ds, "--out", tmp_path / "m.npz", "-M", "2", "-q", "3", "--n-init", "1",
                           "--no-progress")
    assert code == 2 and "train-00000-of-00001.parquet: not listed in" in output


def _write_masks(folder, masks, names, scale):
    for k, name in enumerate(names):
        (folder / name).mkdir(parents=True)
        for i in range(len(masks)):
            cv2.imwrite(str(folder / name / f"f{i:02d}.png"), (masks[i, k] * scale).astype(np.uint8))


def _joints(path):
    table = pq.read_table(path).to_pandas()
    return np.stack([table[[f"{j}_x", f"{j}_y", f"{j}_z"]].to_numpy() for j in JOINT_NAMES], axis=1)


def test_infer_reads_0_1_mask_pngs_like_0_255_ones(generated, model, tmp_path):
    test = load_split(generated, "test", with_masks=True)
    names = load_model(model).rig_.names
    assert set(np.unique(test.masks)) == {0, 1}  # the dataset's encoding
    _write_masks(tmp_path / "ones", test.masks, names, 1)
    _write_masks(tmp_path / "bytes", test.masks, names, 255)
    for src in ("ones", "bytes"):
        code, output = silpose("infer", model, tmp_path / src, "--out", tmp_path / f"{src}.parquet")
        assert code == 0, output
    np.testing.assert_array_equal(_joints(tmp_path / "ones.parquet"), _joints(tmp_path / "bytes.parquet"))
    assert np.isfinite(_joints(tmp_path / "ones.parquet")).all()


def test_infer_points_at_threshold_when_masks_are_too_dark(generated, model, tmp_path):
    test = load_split(generated, "test", with_masks=True)
    names = load_model(model).rig_.names
    # JPEG masks at 0/100 (many grey levels: a grey mask, thresholded at 127): too dark
    for k, name in enumerate(names):
        (tmp_path / "dim" / name).mkdir(parents=True)
        for i in range(len(test.masks)):
            cv2.imwrite(str(tmp_path / "dim" / name / f"f{i:02d}.jpg"), (test.masks[i, k] * 100).astype(np.uint8))
    code, output = silpose("infer", model, tmp_path / "dim", "--out", tmp_path / "dim.parquet")
    assert code == 2 and "usable silhouette" in output and "--threshold" in output
    code, output = silpose("infer", model, tmp_path / "dim", "--out", tmp_path / "dim.parquet", "--threshold", "50")
    assert code == 0, output
    # the same masks as PNG (two levels, no white: a label mask, silpose.app.inputs.mask_images) read as they are
    _write_masks(tmp_path / "label", test.masks, names, 100)
    code, output = silpose("infer", model, tmp_path / "label", "--out", tmp_path / "label.parquet")
    assert code == 0, output


def test_infer_reads_jpeg_and_bmp_mask_folders_like_png_ones(generated, model, tmp_path):
    """Labs' background subtraction often saves JPEG masks: read with a 3x3 median, their contours match the PNG
    masks' within 0.3 px of symmetric Chamfer on average (2 px at worst, JPEG quality 40) (the reference: the same masks written losslessly); a frame saved twice is an error."""
    from silpose.app.inputs.silhouettes import read_png_input

    test = load_split(generated, "test", with_masks=True)
    m = load_model(model)
    names = m.rig_.names
    _write_masks(tmp_path / "png", test.masks, names, 255)
    for suffix, params in ((".jpg", [cv2.IMWRITE_JPEG_QUALITY, 40]), (".bmp", [])):
        folder = tmp_path / suffix[1:]
        for k, cam in enumerate(names):
            (folder / cam).mkdir(parents=True)
            for i, mask in enumerate(test.masks[:, k]):
                assert cv2.imwrite(str(folder / cam / f"{i:04d}{suffix}"), mask * 255, params)
    _, ref, ref_present, _ = read_png_input(m, tmp_path / "png")
    for kind in ("jpg", "bmp"):
        frames, got, present, _ = read_png_input(m, tmp_path / kind)
        np.testing.assert_array_equal(present, ref_present)
        if kind == "bmp":  # lossless: the same contours
            np.testing.assert_array_equal(got, ref)
        else:  # the outline within a pixel (symmetric Chamfer; the start point along it may move)
            _, sym = chamfer_errors(ref, got, (m.rig_[0].height, m.rig_[0].width))
            assert np.nanmean(sym) < 0.3 and np.nanmax(sym) < 2.0, (np.nanmean(sym), np.nanmax(sym))
    cv2.imwrite(str(tmp_path / "jpg" / names[0] / "0000.png"), test.masks[0, 0] * 255)
    code, output = silpose("infer", model, tmp_path / "jpg", "--out", tmp_path / "twice.parquet")
    assert code == 2 and "frame '0000' is also 0000.jpg" in output


def test_infer_says_a_file_is_not_an_input_folder(model, tmp_path):
    notes = tmp_path / "notes.md"
    notes.write_text("# notes\n")
    code, output = silpose("infer", model, notes, "-o", tmp_path / "j.parquet")
    assert code == 2
    assert f"{notes}: a file, but the input is a dataset folder" in output and "no such folder" not in output
