"""`silpose eval --test-data`: one model on other datasets' test splits (e.g. test sets generated from
motion-capture clips), one report folder each and a side-by-side table recomputed here from the rows."""

from __future__ import annotations

import json
import shutil

import pandas as pd
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from silpose.model.persistence import save_model
from silpose.app.training import fit_dataset
from silpose.model.shape_model import ShapeStructureModel
from silpose.shared.cli import build_app
from silpose.shared.dataset import load_split


@pytest.fixture(scope="module")
def model_file(stick_dataset, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("testsets")
    model = fit_dataset(ShapeStructureModel(n_components=2, n_latent=4, n_init=1, max_iter=20, tol=1e-3,
                                            random_state=0), load_split(stick_dataset, "train"))
    save_model(tmp / "m.npz", model)
    return tmp / "m.npz"


def _other_test_set(src, dst, n_keep=None, shift_camera=False):
    """A copy of ``src`` holding only its test split (optionally a camera moved in the metadata)."""
    dst.mkdir()
    for p in src.glob("test-*.parquet"):
        table = pq.read_table(p)
        if n_keep is not None:
            table = table.slice(0, n_keep)
        if shift_camera:
            meta = json.loads(table.schema.metadata[b"silpose"])
            meta["cameras"][0]["t"][0] += 0.5
            table = table.replace_schema_metadata({b"silpose": json.dumps(meta).encode()})
        pq.write_table(table, dst / p.name)
    return dst


def test_one_model_on_several_test_sets(stick_dataset, model_file, tmp_path):
    a = _other_test_set(stick_dataset, tmp_path / "mocap-walk", n_keep=5)
    b = _other_test_set(stick_dataset, tmp_path / "mocap-other", n_keep=3)
    out = tmp_path / "report"
    res = CliRunner().invoke(build_app(), ["eval", str(stick_dataset), "--model", str(model_file), "--out", str(out),
                                           "--experiments", "E2,E4", "--test-data", str(a), "--test-data", str(b)])
    assert res.exit_code == 0, res.output + repr(res.exception)
    table = (out / "test_sets.md").read_text().splitlines()
    rows = [ln for ln in table if ln.startswith("| mocap-")]
    assert [r.split(" | ")[0] for r in rows] == ["| mocap-walk", "| mocap-other"]
    for row, name, n in zip(rows, ("mocap-walk", "mocap-other"), (5, 3)):
        assert (out / name / "summary.md").is_file()
        df = pd.read_parquet(out / name / "results.parquet")
        e2 = df[(df["experiment"] == "E2") & (df["n_input_views"] == 4)]
        assert len(e2) == n
        cells = row.strip("| ").split(" | ")
        assert cells[1] == str(n)
        assert float(cells[2]) == pytest.approx(e2["pose_cm"].mean(), abs=0.006)
        chance = df[(df["experiment"] == "E4") & (df["method"] == "chance")]["pose_cm"].mean()
        assert float(cells[-1]) == pytest.approx(chance, abs=0.006)  # the last column
        mlp = df[(df["experiment"] == "E4") & (df["method"] == "mlp") & (df["n_input_views"] == 4)]["pose_cm"].mean()
        assert float(cells[6]) == pytest.approx(mlp, abs=0.006)  # "MLP 4 views"
        assert json.loads((out / name / "headline.json").read_text())["settings"]["test_data"] == str(
            a if name == "mocap-walk" else b)


def test_a_test_set_seen_by_other_cameras_is_refused(stick_dataset, model_file, tmp_path):
    moved = _other_test_set(stick_dataset, tmp_path / "moved", shift_camera=True)
    res = CliRunner().invoke(build_app(), ["eval", str(stick_dataset), "--model", str(model_file), "--out",
                                           str(tmp_path / "r"), "--experiments", "E2", "--test-data", str(moved)])
    assert res.exit_code == 2
    assert f"{moved}: its cameras differ from those of the training data" in res.output
    shutil.rmtree(moved)
