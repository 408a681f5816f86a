"""``silpose validate``: its geometric checks against brute force, and detection of tampered data."""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from silpose.datagen.config import load_config
from silpose.datagen.pipeline import dataset_metadata, generate
from silpose.datagen.preview import write_preview
from silpose.datagen.validate import contour_boundary_distance, joints_inside, validate_dataset
from silpose.shared.dataset import load_split, write_shard

SYNTH = "silpose.datagen.testing:synthetic_render_samples"
TINY = """name = "tiny"
seed = 3
renderer = "raster"
shard_size = 4
n_points = 100
max_redraws = 50
[splits]
train = 8
test = 4
"""


def test_contour_boundary_distance_matches_brute_force():
    rng = np.random.default_rng(0)
    mask = np.zeros((40, 50), np.uint8)
    mask[8:30, 10:35] = 1
    mask[15:20, 20:28] = 0  # a hole: its rim is boundary too
    mask[30:36, 12:16] = 1
    pts = rng.uniform([2, 2], [47, 37], size=(60, 2))
    ys, xs = np.nonzero(mask)
    fg = set(zip(ys.tolist(), xs.tolist()))
    boundary = np.array([(x, y) for y, x in fg
                         if any((y + dy, x + dx) not in fg for dy, dx in ((1, 0), (-1, 0), (0, 1), (0, -1)))], float)
    # brute force at the 4 surrounding pixel centres, interpolated bilinearly like the implementation
    def exact(p):
        return np.sqrt(((boundary - p) ** 2).sum(1)).min()

    got = contour_boundary_distance(mask, pts)
    for p, g in zip(pts, got):
        x0, y0 = np.floor(p).astype(int)
        fx, fy = p - [x0, y0]
        ref = (exact([x0, y0]) * (1 - fx) * (1 - fy) + exact([x0 + 1, y0]) * fx * (1 - fy)
               + exact([x0, y0 + 1]) * (1 - fx) * fy + exact([x0 + 1, y0 + 1]) * fx * fy)
        assert g == pytest.approx(ref, abs=1e-3)
    on = boundary[rng.choice(len(boundary), 10)]
    np.testing.assert_allclose(contour_boundary_distance(mask, on), 0, atol=1e-6)


def test_joints_inside_matches_a_loop():
    rng = np.random.default_rng(1)
    masks = (rng.random((3, 2, 20, 30)) < 0.5).astype(np.uint8)
    px = rng.uniform(-3, 33, size=(3, 2, 19, 2))
    got = joints_inside(masks, px)
    for n in range(3):
        for k in range(2):
            for j in range(19):
                x, y = int(np.rint(px[n, k, j, 0])), int(np.rint(px[n, k, j, 1]))
                want = 0 <= x < 30 and 0 <= y < 20 and masks[n, k, y, x] == 1
                assert got[n, k, j] == want


@pytest.fixture
def dataset(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text(TINY)
    cfg = load_config(p)
    generate(cfg, tmp_path / "ds", workers=1, render=SYNTH, progress=False)
    return cfg, tmp_path / "ds"


def _rewrite(cfg, path, change):
    """Rewrite a shard's records with ``change(records)`` applied (through the normal writer)."""
    from silpose.datagen.testing import synthetic_render_samples

    ids = pq.read_table(path, columns=["sample_id"]).column("sample_id").to_pylist()
    split = path.name.split("-")[0]
    recs = synthetic_render_samples(cfg.worker_config(), split, ids)
    change(recs)
    write_shard(path, recs, dataset_metadata(cfg))


def test_clean_dataset_passes_and_reports_per_view_figures(dataset):
    cfg, root = dataset
    report = validate_dataset(root)
    assert report.ok, report.format()
    text = report.format()
    assert "height px" in text and "OK: no problems found" in text
    train = load_split(root, "train", with_masks=True)
    for k in range(train.n_views):  # independent per-sample loop over mask rows
        heights = []
        for m in train.masks[:, k]:
            rows = np.nonzero(m.any(1))[0]
            heights.append(rows[-1] - rows[0] + 1)
        view = report.splits["train"]["views"][k]
        assert view["height"] == pytest.approx(np.mean(heights))
        assert view["area"] == pytest.approx(train.extra["area"][:, k].mean())
        assert view["contour_length"] == pytest.approx(train.extra["contour_length"][:, k].mean(), rel=1e-6)


def test_moved_joints_are_reported(dataset):
    cfg, root = dataset

    def lift(recs):
        for r in recs:
            r["joints"] = r["joints"] + np.float32([0, 0, 3.0])

    _rewrite(cfg, root / "train-00001-of-00002.parquet", lift)
    report = validate_dataset(root)
    text = "\n".join(report.problems)
    assert "sha256 differs from manifest.json" in text
    assert "non-terminal joints project inside" in text
    assert report.splits["train"]["joints_inside"] == pytest.approx(0.5, abs=0.02)


def test_shifted_contours_are_reported(dataset):
    cfg, root = dataset

    def shift(recs):
        for r in recs:
            r["contours"] = r["contours"] + np.float32(4.0)

    _rewrite(cfg, root / "test-00000-of-00001.parquet", shift)
    text = "\n".join(validate_dataset(root).problems)
    assert "column 'contours': a point lies" in text
    assert "'contour_centroid'/'contour_scale' disagree" in text


def test_counts_and_missing_shards_against_the_manifest(dataset):
    cfg, root = dataset
    m = json.loads((root / "manifest.json").read_text())
    m["counts"]["test"] = 5
    (root / "manifest.json").write_text(json.dumps(m))
    text = "\n".join(validate_dataset(root).problems)
    assert "split 'test' has 4 samples, manifest.json says 5" in text
    (root / "train-00001-of-00002.parquet").unlink()
    text = "\n".join(validate_dataset(root).problems)
    assert "lacks shard(s) ['train-00001-of-00002.parquet']" in text


def test_preview_png(dataset):
    _, root = dataset
    out = write_preview(root, n_samples=3)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.image as mpimg

    img = mpimg.imread(out)
    assert img.shape[0] > 200 and img.shape[1] > 400


def test_preview_out_never_replaces_a_users_file(dataset, tmp_path):
    from typer.testing import CliRunner

    from silpose.shared.cli import build_app

    _, root = dataset
    mine = tmp_path / "holiday.png"
    mine.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 64)  # someone else's PNG (no silpose tag)
    before = mine.read_bytes()
    r = CliRunner().invoke(build_app(), ["preview", str(root), "--out", str(mine)])
    assert r.exit_code != 0 and "which silpose did not write" in r.output and mine.read_bytes() == before
    ours = tmp_path / "sheet.png"
    for _ in range(2):  # new, then silpose's own picture replaced
        r = CliRunner().invoke(build_app(), ["preview", str(root), "--out", str(ours), "--samples", "2"])
        assert r.exit_code == 0, r.output
