"""Every ``silpose`` command's help shows its text whole (issue 13: ``gen-frames --help`` lost the text
"[frames]", which rich read as markup). Square-bracketed words in a command's docstring or in a
parameter's help must survive rendering."""

from __future__ import annotations

import re

import pytest
import typer
from typer.testing import CliRunner

from silpose.shared.cli import build_app

BRACKETED = re.compile(r"\[[A-Za-z_][\w.-]*\]")  # [frames], [rig], ... (not "[default: x]", added by typer)
APP = build_app()
COMMANDS = typer.main.get_command(APP).commands


def _texts(command) -> list[str]:
    texts = [command.help or ""]
    texts += [getattr(p, "help", None) or "" for p in command.params]
    return texts


def _squash(text: str) -> str:
    """Help text without box drawing, line breaks and repeated spaces (rich wraps and frames it)."""
    text = re.sub(r"[│╭╮╰╯─]", " ", text)
    return re.sub(r"\s+", " ", text)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_bracketed_words_survive_in_help(name):
    wanted = sorted({m.group(0) for t in _texts(COMMANDS[name]) for m in BRACKETED.finditer(t.replace("\\[", "["))})
    res = CliRunner().invoke(APP, [name, "--help"], env={"COLUMNS": "400"})
    assert res.exit_code == 0, res.output
    shown = _squash(res.output)
    missing = [w for w in wanted if w not in shown]
    assert not missing, f"silpose {name} --help lost {missing}"


def test_gen_frames_help_names_the_frames_section():
    res = CliRunner().invoke(APP, ["gen-frames", "--help"], env={"COLUMNS": "400"})
    assert "its [frames] section sets the sizes" in _squash(res.output)
