"""The calibration formats are one registry (silpose.app.rig.formats.FORMATS): ``rig import --help``, the
"unknown format" and "--format" errors and the README's table are generated from it, every entry has one
signature, and importing the registry stays light (no numpy, no OpenCV: ``silpose --help`` loads it)."""

from __future__ import annotations

import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from silpose.app.rig.formats import FORMATS, detect_format, formats_table, get_format, read_calibrations
from silpose.shared.camera import RigError
from silpose.shared.cli import build_app

README = Path(__file__).resolve().parents[3] / "README.md"


def test_every_entry_has_one_signature():
    assert len({f.name for f in FORMATS}) == len(FORMATS)
    for f in FORMATS:
        assert list(inspect.signature(f.read).parameters) == ["p", "ctx"], f.name
        assert len(inspect.signature(f.detect).parameters) == 1, f.name


def test_help_lists_every_format():
    res = CliRunner().invoke(build_app(), ["rig", "import", "--help"], env={"COLUMNS": "80"})
    shown = " ".join(res.output.split())
    for f in FORMATS:
        assert f.name in shown and " ".join(f.files.split()) in shown, f.name


def test_unknown_format_error_lists_every_format(tmp_path):
    odd = tmp_path / "calib.ini"
    odd.write_text("x")
    with pytest.raises(RigError) as err:
        detect_format(odd)
    for f in FORMATS:
        assert f.files in str(err.value), f.name
    with pytest.raises(RigError, match="--format: must be one of auto, " + re.escape(", ".join(f.name for f in FORMATS[:-1]))):
        read_calibrations([odd], fmt="nope")
    with pytest.raises(RigError, match="got 'nope'"):
        get_format("nope")


def test_readme_table_is_the_registry():
    text = README.read_text(encoding="utf-8")
    table = text.split("<!-- formats:start -->", 1)[1].split("<!-- formats:end -->", 1)[0].strip()
    assert table == formats_table(), "README's format table differs: paste silpose.app.rig.formats.formats_table()"


def test_registry_import_is_light():
    code = "import sys, silpose.app.rig.formats; print('numpy' in sys.modules or 'cv2' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
