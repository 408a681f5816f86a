"""silpose.app.writers: output file names derived from the joints file."""

from __future__ import annotations

from pathlib import Path

from silpose.app.writers import sibling


def test_sibling_names_the_outputs_after_the_joints_file():
    assert sibling(Path("out/j.parquet"), ".contours.npz") == Path("out/j.contours.npz")
    assert sibling(Path("a.b.json"), ".overlays") == Path("a.b.overlays")
