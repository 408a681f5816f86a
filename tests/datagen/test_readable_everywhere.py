"""A generated dataset loads with Hugging Face ``datasets`` (both ways), pyarrow, pandas, DuckDB and
Polars without silpose code, masks show as images, and the card's YAML carries license, task and
size categories and the paper's BibTeX.

The data come from the pipeline with the synthetic stand-in renderer (stick figures, not Blender);
the reference is silpose's own reader.
"""

from __future__ import annotations

import json
import os

os.environ.setdefault("HF_HUB_OFFLINE", "1")  # local files only: never ask the Hub
os.environ.setdefault("HF_DATASETS_DISABLE_PROGRESS_BARS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402
import pytest  # noqa: E402
import yaml  # noqa: E402

from silpose.datagen.card import size_category  # noqa: E402
from silpose.datagen.pipeline import generate  # noqa: E402
from silpose.datagen.testing import SYNTH_RENDER, tiny_config, tiny_config_toml  # noqa: E402
from silpose.shared.dataset import load_split  # noqa: E402

K, N_POINTS, H, W = 4, 200, 240, 320
COUNTS = {"train": 8, "test": 4}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("everywhere")
    cfg = tiny_config(tmp, tiny_config_toml(seed=5, shard_size=3))
    out = tmp / "tiny"
    generate(cfg, out, workers=1, render=SYNTH_RENDER, progress=False, card=True)
    ref = {s: load_split(out, s, with_masks=True) for s in COUNTS}
    return out, ref


def _front_matter(card: str) -> dict:
    assert card.startswith("---\n")
    return yaml.safe_load(card.split("---\n")[1])


def _png_masks(images: list) -> np.ndarray:
    """(K, H, W) bool from a row's list of ``{bytes, path}`` structs, decoded without silpose."""
    return np.stack([cv2.imdecode(np.frombuffer(im["bytes"], np.uint8), cv2.IMREAD_UNCHANGED) > 0 for im in images])


@pytest.mark.parametrize("how", ["parquet data_files", "dataset folder (card YAML)"])
def test_hugging_face_datasets_loads_every_split_with_shapes_and_images(dataset, how, tmp_path):
    datasets = pytest.importorskip("datasets")
    out, ref = dataset
    if how == "parquet data_files":
        hf = datasets.load_dataset("parquet", data_files={s: str(out / f"{s}-*.parquet") for s in COUNTS},
                                   cache_dir=str(tmp_path / "hf"))
    else:
        hf = datasets.load_dataset(str(out), cache_dir=str(tmp_path / "hf"))
    assert {s: hf[s].num_rows for s in hf} == COUNTS
    features = hf["train"].features
    assert isinstance(features["masks"], datasets.List) and isinstance(features["masks"].feature, datasets.Image)
    assert features["masks"].length == K
    for split, n in COUNTS.items():
        ds = hf[split]
        arrays = ds.with_format("numpy")[:]
        np.testing.assert_array_equal(arrays["sample_id"], ref[split].sample_id)  # shard order kept
        assert arrays["joints"].shape == (n, 19, 3) and arrays["joints"].dtype == np.float32
        assert arrays["contours"].shape == (n, K, N_POINTS, 2)
        assert arrays["contour_centroid"].shape == (n, K, 2) and arrays["touches_border"].shape == (n, K)
        np.testing.assert_array_equal(arrays["joints"], ref[split].joints)
        np.testing.assert_array_equal(arrays["contours"], ref[split].contours)
        np.testing.assert_array_equal(arrays["contour_scale"], ref[split].scale)
        assert arrays["masks"].shape == (n, K, H, W)
        np.testing.assert_array_equal(arrays["masks"].astype(np.uint8), ref[split].masks)
        row = ds[n - 1]  # default format: the masks are PIL images, black and white
        assert [im.mode for im in row["masks"]] == ["1"] * K and row["masks"][0].size == (W, H)
        np.testing.assert_array_equal(np.stack([np.asarray(im) for im in row["masks"]]).astype(np.uint8),
                                      ref[split].masks[n - 1])
        assert row["subject"].keys() == ref[split].subject.keys()
        assert ref[split].masks.sum() > 0


def test_pyarrow_pandas_duckdb_polars_read_it_without_silpose(dataset):
    duckdb = pytest.importorskip("duckdb")
    pl = pytest.importorskip("polars")
    out, ref = dataset
    tr = ref["train"]
    n = COUNTS["train"]
    files = sorted(out.glob("train-*.parquet"))

    table = pq.read_table(files).sort_by("sample_id")  # pyarrow
    np.testing.assert_array_equal(table["joints"].combine_chunks().flatten().flatten().to_numpy().reshape(n, 19, 3),
                                  tr.joints)
    masks = table["masks"].to_pylist()
    np.testing.assert_array_equal(np.stack([_png_masks(m) for m in masks]).astype(np.uint8), tr.masks)

    df = table.select(["sample_id", "contours", "masks", "gait"]).to_pandas()  # pandas
    contours = np.stack([np.stack([np.stack(view) for view in c]) for c in df["contours"]])  # nested object arrays
    np.testing.assert_array_equal(contours, tr.contours)
    np.testing.assert_array_equal(_png_masks(list(df["masks"].iloc[2])).astype(np.uint8), tr.masks[2])
    np.testing.assert_allclose(df["gait"].map(lambda g: g["phase"]).to_numpy(), tr.gait["phase"], rtol=1e-6)

    con = duckdb.connect()  # DuckDB: nested lists are arrays, images are structs with a BLOB
    rows = con.sql(f"SELECT joints, masks[1].bytes, contour_scale FROM read_parquet('{out}/train-*.parquet') "
                   "ORDER BY sample_id").fetchall()
    np.testing.assert_array_equal(np.array([r[0] for r in rows], np.float32), tr.joints)
    first_view = np.stack([cv2.imdecode(np.frombuffer(r[1], np.uint8), cv2.IMREAD_UNCHANGED) > 0 for r in rows])
    np.testing.assert_array_equal(first_view.astype(np.uint8), tr.masks[:, 0])
    np.testing.assert_array_equal(np.array([r[2] for r in rows], np.float32), tr.scale)
    counts = dict(con.sql(f"SELECT split, count(*) FROM read_parquet('{out}/*.parquet') GROUP BY split").fetchall())
    assert counts == COUNTS

    frame = pl.read_parquet(str(out / "train-*.parquet"), columns=["sample_id", "contours", "masks"]).sort("sample_id")
    np.testing.assert_array_equal(frame["contours"].to_numpy().astype(np.float32), tr.contours)  # Polars
    np.testing.assert_array_equal(_png_masks(frame["masks"][5]).astype(np.uint8), tr.masks[5])


def test_card_yaml_has_license_tasks_size_and_configs(dataset):
    out, _ = dataset
    card = (out / "README.md").read_text()
    meta = _front_matter(card)
    assert meta["license"] == "cc-by-4.0"
    assert meta["task_categories"] == ["image-to-3d", "keypoint-detection"]
    assert meta["size_categories"] == ["n<1K"]  # 12 rows
    assert meta["configs"] == [{"config_name": "default", "data_files": [
        {"split": "train", "path": "train-*.parquet"}, {"split": "test", "path": "test-*.parquet"}]}]
    assert "synthetic" in meta["tags"] and meta["pretty_name"] == "silpose tiny"
    bib = card[card.index("```bibtex"):]
    for part in ("@inproceedings{", "Grauman, Kristen and Shakhnarovich, Gregory and Darrell, Trevor",
                 "Inferring {3D} Structure with a Statistical Image-Based Shape Model", "year      = {2003}",
                 "pages     = {641--647}", "Computer Vision (ICCV)"):
        assert part in bib, part
    assert "list<image>[4]" in card  # the schema table names the new layout


@pytest.mark.parametrize("n, label", [(0, "n<1K"), (999, "n<1K"), (1000, "1K<n<10K"), (2500, "1K<n<10K"),
                                      (23_000, "10K<n<100K"), (200_000, "100K<n<1M"), (10**12, "n>1T")])
def test_size_category_uses_hugging_face_buckets(n, label):
    assert size_category(n) == label


def test_a_version_1_dataset_validates_with_a_note_and_gen_upgrades_it(tmp_path, write_v1_shard):
    """The previous format still reads and validates (with a one-line note to regenerate); ``gen`` into
    the same folder rewrites its shards in the current format, identical to a fresh run."""
    from silpose.datagen.manifest import MANIFEST, sha256_file
    from silpose.datagen.pipeline import dataset_metadata
    from silpose.datagen.testing import synthetic_render_samples
    from silpose.datagen.validate import validate_dataset

    cfg = tiny_config(tmp_path)
    fresh = generate(cfg, tmp_path / "fresh", workers=1, render=SYNTH_RENDER, progress=False)
    old = tmp_path / "old"
    generate(cfg, old, workers=1, render=SYNTH_RENDER, progress=False)
    manifest = json.loads((old / MANIFEST).read_text())
    for entry in manifest["shards"]:
        path = old / entry["file"]
        ids = pq.read_table(path, columns=["sample_id"]).column("sample_id").to_pylist()
        write_v1_shard(path, synthetic_render_samples(cfg.worker_config(), entry["file"].split("-")[0], ids),
                       dataset_metadata(cfg))
        entry["sha256"] = sha256_file(path)
    (old / MANIFEST).write_text(json.dumps(manifest))

    report = validate_dataset(old)
    assert report.ok, report.format()
    notes = [n for n in report.notes if "format version 1" in n]
    assert len(notes) == 2 and "regenerate" in notes[0] and "\n" not in notes[0]
    np.testing.assert_array_equal(load_split(old, "train", with_masks=True).masks,
                                  load_split(tmp_path / "fresh", "train", with_masks=True).masks)

    again = generate(cfg, old, workers=1, render=SYNTH_RENDER, progress=False)
    assert again["timing"]["shards_skipped"] == 0
    assert [s["sha256"] for s in again["shards"]] == [s["sha256"] for s in fresh["shards"]]
    assert not [n for n in validate_dataset(old).notes if "format version" in n]
