"""One error contract for every command (docs/conventions.md, "Errors"): one line on stderr,
``silpose CMD: error: <what>`` naming the file or the flag the value came from, exit status 2 for usage and
input errors (1 for failures while running), and nothing left behind by a refused command."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from silpose.shared.cli import build_app


def run(*args: str):
    return CliRunner().invoke(build_app(), list(args), env={"COLUMNS": "80"})


def one_line(res, command: str) -> str:
    assert res.stderr.count("\n") == 1 and res.stderr.startswith(f"silpose {command}: error: "), res.stderr
    assert "Traceback" not in res.output and "Usage:" not in res.stderr
    return res.stderr


@pytest.mark.parametrize("args,command,flag", [
    (["gen", "smoke", "--seed", "-1"], "gen", "(--seed)"),
    (["train", "nowhere", "--heldout", "-0.5"], "train", "(--heldout)"),
    (["train", "nowhere", "--heldout", "1"], "train", "(--heldout)"),
    (["infer", "m.npz", "in", "--noise-variance", "-1"], "infer", "(--noise-variance)"),
    (["gen", "--workers", "0"], "gen", "(--workers / -j)"),
])
def test_a_bad_flag_value_names_the_flag(args, command, flag):
    res = run(*args)
    assert res.exit_code == 2
    message = one_line(res, command)
    assert message.rstrip().endswith(flag)
    assert ".toml" not in message  # not blamed on the preset's config file


def test_an_unknown_option_is_one_line():
    res = run("train", "--no-such-option")
    assert res.exit_code == 2
    assert "--no-such-option" in one_line(res, "train")


def test_a_missing_dataset_folder_has_one_exit_status(tmp_path):
    codes = set()
    for command in ("validate", "train"):
        res = run(command, str(tmp_path / "nowhere"), *(["-o", str(tmp_path / "m.npz")] if command == "train" else []))
        assert str(tmp_path / "nowhere") in one_line(res, command)
        codes.add(res.exit_code)
    assert codes == {2}


def test_a_text_file_as_model_is_not_explained_with_pickle(tmp_path):
    model = tmp_path / "m.npz"
    model.write_text("hello\n")
    (tmp_path / "in").mkdir()
    res = run("infer", str(model), str(tmp_path / "in"), "-o", str(tmp_path / "j.parquet"))
    assert res.exit_code == 2
    message = one_line(res, "infer")
    assert "allow_pickle" not in message and "pickle" not in message and str(model) in message
