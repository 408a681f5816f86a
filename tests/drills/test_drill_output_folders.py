"""Drills: every writing command keeps a user's files byte for byte (issue 13, item 1).

``gen``, ``gen-frames`` and ``eval`` write folders: pointed at a folder holding a user's files (a
README.md, a manifest.json, a ``.*.tmp`` draft, a subfolder), each refuses with one line naming the
folder and those files, before any work, and the folder is unchanged (no marker either). ``train``
and ``infer`` write named files: they refuse to replace a file silpose did not write, and writing a
new file next to the user's leaves the user's files byte for byte. Paths resolving to the working
folder or its parents (``.``, ``..``, a config ``name = ".."``) are refused.

The commands run through the real ``silpose`` command (typer's CliRunner, in process).
"""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from silpose.datagen.pipeline import generate
from silpose.datagen.testing import SYNTH_RENDER, synthetic_record, tiny_config, tiny_config_toml
from silpose.shared.camera import default_rig
from silpose.shared.cli import build_app
from silpose.shared.dataset import write_shard
from silpose.shared.dataset_schema import build_metadata
from silpose.shared.output_dir import claim_folder, read_marker

N_POINTS = 24
USER_FILES = ("README.md", "manifest.json", ".draft.tmp", "results.bin", "sub/notes.txt")


def silpose(*args):
    res = CliRunner().invoke(build_app(), [str(a) for a in args])
    return res.exit_code, res.output


def error_line(output: str, command: str) -> str:
    lines = [line for line in output.splitlines() if line.startswith(f"silpose {command}: error: ")]
    assert len(lines) == 1, output
    return lines[0]


def user_folder(path):
    """A folder of a user's own files (names the commands themselves write among them)."""
    path.mkdir(parents=True)
    (path / "README.md").write_text("# My project\n\nHand-written notes.\n")
    (path / "manifest.json").write_text('{"my": "manifest"}\n')
    (path / ".draft.tmp").write_bytes(b"an unsaved draft, named like a silpose temporary")
    (path / "results.bin").write_bytes(np.random.default_rng(0).bytes(4096))
    (path / "sub").mkdir()
    (path / "sub" / "notes.txt").write_text("more notes\n")
    return path


def snapshot(folder):
    """{relative path: bytes} of every file under ``folder`` (hidden ones included)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """A tiny dataset (80 train, 6 test stick figures) in the dataset format, with a manifest without shard list."""
    root = tmp_path_factory.mktemp("drill-out") / "tiny"
    root.mkdir()
    rig = default_rig()
    config = {"name": "tiny", "seed": 3, "rig": rig.to_dict(), "n_points": N_POINTS}
    meta = build_metadata(rig.to_dict()["cameras"], config, N_POINTS, generator_version="test")
    for split, n in (("train", 80), ("test", 6)):
        write_shard(root / f"{split}-00000-of-00001.parquet", [synthetic_record(config, split, i) for i in range(n)], meta)
    (root / "manifest.json").write_text(json.dumps({"name": "tiny"}))
    return root


@pytest.fixture(scope="module")
def model(dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("drill-models") / "tiny.npz"
    code, output = silpose("train", dataset, "--out", out, "-M", "2", "-q", "4", "--n-init", "1", "--max-iter", "20",
                           "--no-progress")
    assert code == 0, output
    return out


# ------------------------------------------------------------------ folder commands: gen, gen-frames, eval


def test_gen_into_a_users_folder_is_refused_and_keeps_every_byte(tmp_path):
    tiny_config(tmp_path)
    folder = user_folder(tmp_path / "mine")
    before = snapshot(folder)
    code, output = silpose("gen", tmp_path / "tiny.toml", "--out", folder, "--no-progress")
    assert code == 2
    line = error_line(output, "gen")
    assert str(folder) in line and all(name in line for name in (".draft.tmp", "README.md", "manifest.json", "sub"))
    assert snapshot(folder) == before and read_marker(folder) is None


def test_gen_frames_into_a_users_folder_is_refused_and_keeps_every_byte(tmp_path):
    folder = user_folder(tmp_path / "mine")
    before = snapshot(folder)
    code, output = silpose("gen-frames", "smoke", "--out", folder, "--no-progress")
    assert code == 2
    line = error_line(output, "gen-frames")
    assert str(folder) in line and "README.md" in line and ".draft.tmp" in line
    assert snapshot(folder) == before
    assert not list(tmp_path.glob(".*partial*"))  # nothing was started next to it either


def test_eval_into_a_users_folder_is_refused_before_any_work_and_keeps_every_byte(tmp_path, dataset, model):
    folder = user_folder(tmp_path / "mine")
    before = snapshot(folder)
    code, output = silpose("eval", dataset, "--model", model, "--out", folder)
    assert code == 2
    line = error_line(output, "eval")
    assert str(folder) in line and "README.md" in line and "results.bin" in line
    assert snapshot(folder) == before


def test_eval_into_a_folder_of_another_command_is_refused(tmp_path, dataset, model):
    silpose_gen_folder = claim_folder(tmp_path / "ds", "gen")  # what `silpose gen` does first
    generate(tiny_config(tmp_path), silpose_gen_folder, workers=1, render=SYNTH_RENDER, progress=False)
    before = snapshot(silpose_gen_folder)
    code, output = silpose("eval", dataset, "--model", model, "--out", silpose_gen_folder)
    assert code == 2 and "holds the output of 'silpose gen'" in error_line(output, "eval")
    assert snapshot(silpose_gen_folder) == before


# ------------------------------------------------------------------ paths that are never output folders


@pytest.mark.parametrize("out", [".", ".."])
def test_gen_into_the_working_folder_or_its_parent_is_refused(tmp_path, monkeypatch, out):
    project = user_folder(tmp_path / "project")
    tiny_config(project / "sub")
    before = snapshot(tmp_path)
    monkeypatch.chdir(project)
    code, output = silpose("gen", "sub/tiny.toml", "--out", out, "--no-progress")
    assert code == 2 and "the working folder" in error_line(output, "gen")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("name", ["..", "."])
def test_a_config_named_dot_dot_cannot_write_into_the_project(tmp_path, monkeypatch, name):
    project = user_folder(tmp_path / "project")
    (project / "cfg.toml").write_text(tiny_config_toml().replace('name = "tiny"', f'name = "{name}"'))
    before = snapshot(tmp_path)
    monkeypatch.chdir(project)
    code, output = silpose("gen", "cfg.toml", "--no-progress")  # default output data/<name>
    assert code == 2 and "field 'name'" in error_line(output, "gen")
    assert snapshot(tmp_path) == before


def test_eval_of_dot_dot_does_not_write_into_the_working_folder(tmp_path, monkeypatch):
    project = user_folder(tmp_path / "project")
    before = snapshot(tmp_path)
    monkeypatch.chdir(project)
    code, output = silpose("eval", "..")  # was reports/.. = the working folder
    assert code == 2
    assert snapshot(tmp_path) == before


# ------------------------------------------------------------------ file commands: train, infer


def test_train_refuses_to_replace_a_users_file_and_keeps_every_byte(tmp_path, dataset):
    folder = user_folder(tmp_path / "mine")
    np.savez(folder / "model.npz", weights=np.arange(3.0))  # the user's own model.npz
    (folder / "model.report.md").write_text("my report\n")
    before = snapshot(folder)
    code, output = silpose("train", dataset, "--out", folder / "model.npz", "-M", "2", "-q", "4", "--n-init", "1",
                           "--max-iter", "5", "--no-progress")
    assert code == 2
    line = error_line(output, "train")
    assert str(folder) in line and "model.npz" in line and "model.report.md" in line
    assert snapshot(folder) == before


def test_train_writes_a_new_model_next_to_a_users_files_and_replaces_only_its_own(tmp_path, dataset):
    folder = user_folder(tmp_path / "mine")
    before = snapshot(folder)
    args = ("train", dataset, "--out", folder / "m.npz", "-M", "2", "-q", "4", "--n-init", "1", "--max-iter", "5",
            "--no-progress")
    for _ in range(2):  # the second run replaces the model and reports silpose wrote
        code, output = silpose(*args)
        assert code == 0, output
    after = snapshot(folder)
    assert {k: v for k, v in after.items() if k in before} == before
    assert sorted(set(after) - set(before)) == ["m.npz", "m.report.json", "m.report.md"]


def test_infer_refuses_to_replace_a_users_files_and_keeps_every_byte(tmp_path, dataset, model):
    folder = user_folder(tmp_path / "mine")
    pq.write_table(pa.table({"mine": [1, 2, 3]}), folder / "joints.parquet")
    (folder / "other.contours.npz").write_bytes(b"the user's, not silpose's")
    before = snapshot(folder)
    code, output = silpose("infer", model, dataset, "--out", folder / "joints.parquet")
    assert code == 2 and "joints.parquet" in error_line(output, "infer")
    code, output = silpose("infer", model, dataset, "--out", folder / "other.json", "--contours")
    assert code == 2 and "other.contours.npz" in error_line(output, "infer")
    code, output = silpose("infer", model, "--frames", tmp_path / "no-frames-needed", "--out", folder / "j.parquet",
                           "--overlays", "png", "--overlay-dir", folder)
    assert code == 2 and "README.md" in error_line(output, "infer")
    assert snapshot(folder) == before


def test_infer_writes_new_files_next_to_a_users_files_and_replaces_only_its_own(tmp_path, dataset, model):
    folder = user_folder(tmp_path / "mine")
    before = snapshot(folder)
    for _ in range(2):
        for out in ("j.parquet", "j.json"):
            code, output = silpose("infer", model, dataset, "--out", folder / out, "--contours")
            assert code == 0, output
    after = snapshot(folder)
    assert {k: v for k, v in after.items() if k in before} == before
    assert sorted(set(after) - set(before)) == ["j.contours.npz", "j.json", "j.parquet"]


# ------------------------------------------------------------------ silpose's own folders stay usable


def test_gen_resumes_a_dataset_written_before_output_markers(tmp_path):
    """A complete dataset without the marker (an older silpose, or the library call) is recognised by its
    manifest: `silpose gen` completes it (nothing left to render) and marks it."""
    cfg = tiny_config(tmp_path)
    generate(cfg, tmp_path / "ds", workers=1, render=SYNTH_RENDER, progress=False)
    assert read_marker(tmp_path / "ds") is None
    shards = {p.name: p.read_bytes() for p in (tmp_path / "ds").glob("*.parquet")}
    code, output = silpose("gen", tmp_path / "tiny.toml", "--out", tmp_path / "ds", "--no-progress", "--no-preview")
    assert code == 0, output
    assert "3 already complete" in output
    assert read_marker(tmp_path / "ds")["command"] == "gen"
    assert {p.name: p.read_bytes() for p in (tmp_path / "ds").glob("*.parquet")} == shards
