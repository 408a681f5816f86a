"""``silpose train --streaming`` and ``--executor ray`` (silpose.app.training) against the in-memory command.

The dataset: several uneven Parquet shards written with the dataset writer
(``silpose.datagen.testing.write_synthetic_dataset``, as in tests/model/test_streaming.py, which tests the
streaming fit itself).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from silpose.datagen.testing import write_synthetic_dataset
from silpose.model.persistence import load_model
from silpose.shared.cli import build_app

pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")

N_POINTS = 16
SHARD_ROWS = (30, 25, 30, 15)  # uneven shards, 100 rows


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return write_synthetic_dataset(tmp_path_factory.mktemp("data") / "sharded", SHARD_ROWS, N_POINTS)


def test_train_cli_streaming_equals_in_memory(dataset, tmp_path):
    """`silpose train --streaming`: same held-out rows, same k-means start (<= 5,000 rows), same model."""
    common = [str(dataset), "-M", "2", "-q", "4", "--n-init", "2", "--max-iter", "15", "--tol", "0", "--no-progress",
              "--roughness", "0", "--mirror", "off"]  # the ragged copies and mirrored people are in-memory only
    paths = {}
    for mode, extra in (("memory", []), ("stream", ["--streaming"])):
        paths[mode] = tmp_path / f"{mode}.npz"
        res = CliRunner().invoke(build_app(), ["train", *common, "--out", str(paths[mode]), *extra])
        assert res.exit_code == 0, res.output
    a, b = load_model(paths["memory"]), load_model(paths["stream"])
    np.testing.assert_allclose(a.mixture_.means_, b.mixture_.means_, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(a.mixture_.components_, b.mixture_.components_, rtol=1e-6, atol=1e-9)
    ra = json.loads(paths["memory"].with_suffix(".report.json").read_text())
    rb = json.loads(paths["stream"].with_suffix(".report.json").read_text())
    assert rb["mode"] == {"streaming": True, "executor": "local", "n_shards": len(SHARD_ROWS)}
    assert ra["mode"]["streaming"] is False and ra["n_fit"] == rb["n_fit"] == 90
    np.testing.assert_allclose(ra["em"]["loglik_curve"], rb["em"]["loglik_curve"], rtol=1e-8)
    np.testing.assert_allclose(ra["heldout"]["mean_loglik"], rb["heldout"]["mean_loglik"], rtol=1e-8)
    np.testing.assert_allclose(ra["heldout"]["joint_error_cm"], rb["heldout"]["joint_error_cm"], rtol=1e-6)
    assert "streamed over 4 shards (local)" in paths["stream"].with_suffix(".report.md").read_text()


def test_train_cli_rejects_select_with_streaming(dataset, tmp_path):
    res = CliRunner().invoke(build_app(), ["train", str(dataset), "--streaming", "--select", "--out",
                                           str(tmp_path / "m.npz"), "--no-progress"])
    assert res.exit_code == 2 and "--select fits its grid in memory" in res.output


def test_app_imports_without_ray():
    code = "import sys; sys.modules['ray'] = None\nimport silpose.app.cli.train, silpose.app.training\nprint('OK')\n"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "OK"


@pytest.mark.ray
def test_train_cli_on_ray(dataset, local_ray, tmp_path):
    out = tmp_path / "ray.npz"
    res = CliRunner().invoke(build_app(), ["train", str(dataset), "-M", "2", "-q", "3", "--n-init", "1",
                                           "--max-iter", "5", "--executor", "ray", "--out", str(out), "--no-progress"])
    assert res.exit_code == 0, res.output
    report = json.loads(out.with_suffix(".report.json").read_text())
    assert report["mode"] == {"streaming": True, "executor": "ray", "n_shards": len(SHARD_ROWS)}
