"""Every ``silpose`` command's help fits an 80-column terminal and shows its text whole.

The command tree is walked, so commands that packages add later are checked too: at ``COLUMNS=80`` no line
is wider than the terminal, every option name and every help text (with its ``[default: ...]``) appears
whole, no ``<bool>`` type is shown and no issue is cited. Square-bracketed words (``[frames]``, ``[rig]``)
survive rendering (rich used to read them as markup)."""

from __future__ import annotations

import re

import pytest
import typer
from typer.testing import CliRunner

from silpose.shared.cli import build_app, silpose_version

BRACKETED = re.compile(r"\[[A-Za-z_][\w.-]*\]")  # [frames], [rig], ... (not "[default: x]", added by typer)
APP = build_app()
ROOT = typer.main.get_command(APP)
WIDTH = 80


def _tree(command, path: tuple[str, ...] = ()) -> list:
    out = [(path, command)]
    if hasattr(command, "commands"):  # a group (typer vendors its own click: no isinstance on click.Group)
        for name, sub in sorted(command.commands.items()):
            out += _tree(sub, path + (name,))
    return out


TREE = _tree(ROOT)
IDS = [" ".join(p) or "silpose" for p, _ in TREE]


def _help(path: tuple[str, ...], columns: int = WIDTH) -> str:
    res = CliRunner().invoke(APP, [*path, "--help"], env={"COLUMNS": str(columns)})
    assert res.exit_code == 0, res.output
    return res.output


def _nospace(text: str) -> str:
    return re.sub(r"\s+", "", text)


def _context(path: tuple[str, ...], command):
    parent = None
    for name in ("silpose", *path[:-1]):
        parent = ROOT.context_class(ROOT, info_name=name, parent=parent)
    return command.context_class(command, info_name=path[-1] if path else "silpose", parent=parent)


def test_tree_holds_every_command():
    names = {p for p, _ in TREE}
    assert {("gen",), ("train",), ("infer",), ("eval",), ("rig", "import"), ("rig", "show")} <= names


@pytest.mark.parametrize("path,command", TREE, ids=IDS)
def test_help_fits_80_columns_and_cuts_nothing(path, command):
    shown = _help(path)
    wide = [line for line in shown.splitlines() if len(line) > WIDTH]
    assert not wide, f"lines wider than {WIDTH}: {wide}"
    assert "…" not in shown
    assert "<bool>" not in shown
    assert "\\[" not in shown, "a rich escape shown literally (plain help needs no backslash before [)"
    assert not re.search(r"\bissues? \d+", shown, re.I), "help cites an issue"
    words = set(re.findall(r"(?<![\w-])-{1,2}[A-Za-z][\w-]*", shown))
    ctx = _context(path, command)
    for param in command.params:
        for opt in [*param.opts, *param.secondary_opts]:
            if opt.startswith("-"):
                assert opt in words, f"option {opt} is not shown whole"
        record = param.get_help_record(ctx)
        if record is not None and record[1]:
            assert _nospace(record[1]) in _nospace(shown), f"help of {param.name} is not shown whole"
    if hasattr(command, "commands"):  # the command list shows each summary whole
        for name, sub in command.commands.items():
            assert _nospace(sub.get_short_help_str(limit=10_000)) in _nospace(shown), name


@pytest.mark.parametrize("path,command", TREE, ids=IDS)
def test_help_paragraphs_have_no_hard_line_breaks(path, command):
    """The description is wrapped to the terminal, not at the source's line breaks: within a paragraph, the
    next line's first word never fits at the end of the line before it."""
    assert "\b" not in (command.help or "")
    lines = _help(path).splitlines()
    end = next((i for i, line in enumerate(lines) if line.rstrip().endswith(":") and not line.startswith(" ")),
               len(lines))  # "Arguments:", "Options:", "Commands:"
    width = WIDTH - 2  # click's formatter leaves a margin
    ragged = [(a, b) for a, b in zip(lines[1:end], lines[2:end])
              if a.strip() and b.strip() and len(a.rstrip()) + 1 + len(b.split()[0]) <= width]
    assert not ragged, f"lines broken early: {ragged[:3]}"


@pytest.mark.parametrize("path,command", TREE, ids=IDS)
def test_bracketed_words_survive_in_help(path, command):
    texts = [command.help or ""] + [getattr(p, "help", None) or "" for p in command.params]
    wanted = sorted({m.group(0) for t in texts for m in BRACKETED.finditer(t)})
    shown = _nospace(_help(path))
    missing = [w for w in wanted if _nospace(w) not in shown]
    assert not missing, f"silpose {' '.join(path)} --help lost {missing}"


def test_gen_frames_help_names_the_frames_section():
    assert "its [frames] section sets the sizes" in " ".join(_help(("gen-frames",)).split())


def test_version():
    res = CliRunner().invoke(APP, ["--version"])
    assert res.exit_code == 0
    assert res.output.strip() == f"silpose {silpose_version()}"
    assert re.fullmatch(r"\d+\.\d+\.\d+.*", silpose_version())
