"""``silpose eval`` option and input checks: ``--n-test 0`` or ``-5`` printed a 45-line traceback; a refused
evaluation printed a blank line first, named the model twice and left its output folder behind."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from silpose.model.persistence import save_model
from silpose.app.training import fit_dataset
from silpose.model.shape_model import ShapeStructureModel
from silpose.shared.cli import build_app
from silpose.shared.dataset import load_split


@pytest.fixture(scope="module")
def model_path(stick_dataset, tmp_path_factory):
    path = tmp_path_factory.mktemp("eval-inputs") / "m.npz"
    model = ShapeStructureModel(n_components=2, n_latent=4, n_init=1, max_iter=10, random_state=0)
    save_model(path, fit_dataset(model, load_split(stick_dataset, "train")))
    return path


@pytest.mark.parametrize("n_test", ["0", "-5"])
def test_n_test_below_one_is_a_usage_error_without_traceback(n_test, stick_dataset, model_path, tmp_path):
    out = tmp_path / "report"
    res = CliRunner().invoke(build_app(), ["eval", str(stick_dataset), "--model", str(model_path), "--out", str(out),
                                           "--n-test", n_test], env={"COLUMNS": "200"})
    assert res.exit_code == 2, res.output
    assert isinstance(res.exception, SystemExit)  # not a ValueError escaping the command
    assert "Traceback" not in res.output
    assert res.stderr == "silpose eval: error: Input should be greater than or equal to 1 (--n-test)\n"
    assert not out.exists()


def test_a_refused_evaluation_is_one_line_and_leaves_no_folder(stick_dataset, tmp_path):
    text_model = tmp_path / "notes.npz"
    text_model.write_text("not a model\n")
    out = tmp_path / "report"
    res = CliRunner().invoke(build_app(), ["eval", str(stick_dataset), "--model", str(text_model), "--out", str(out)])
    assert res.exit_code == 2
    assert res.stderr.count("\n") == 1 and res.stderr.startswith("silpose eval: error: "), res.stderr
    assert res.stderr.count(str(text_model)) == 1 and "allow_pickle" not in res.stderr
    assert not out.exists()


def test_a_missing_dataset_is_one_line(tmp_path):
    res = CliRunner().invoke(build_app(), ["eval", str(tmp_path / "nowhere"), "--out", str(tmp_path / "r")])
    assert res.exit_code == 2
    assert res.stderr == f"silpose eval: error: {tmp_path / 'nowhere'}: no such dataset folder (generate it first: " \
                         "silpose gen nowhere)\n"
    assert not (tmp_path / "r").exists()
