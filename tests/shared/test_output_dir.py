"""silpose.shared.output_dir: which folders and files a command may write (issue 13, item 1)."""

from __future__ import annotations

import json

import pytest

from silpose.shared.output_dir import (
    MARKER,
    OutputFolderError,
    check_folder,
    check_output_path,
    claim_files,
    claim_folder,
    read_marker,
    repository_root,
)


def snapshot(folder):
    """{relative path: bytes} of every file under ``folder``, hidden ones included."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_new_and_empty_folders_are_claimed_and_marked(tmp_path):
    new = claim_folder(tmp_path / "a" / "b", "gen")
    assert new.is_dir() and read_marker(new) == {"written_by": "silpose", "command": "gen", "format": 1}
    (tmp_path / "empty").mkdir()
    claim_folder(tmp_path / "empty", "eval")
    assert read_marker(tmp_path / "empty")["command"] == "eval"
    assert check_folder(new, "gen") == "marked"  # a second run of the same command may write there again


def test_a_folder_with_foreign_files_is_refused_naming_them_and_left_byte_for_byte(tmp_path):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "README.md").write_text("my notes\n")
    (folder / "manifest.json").write_text('{"mine": true}')
    (folder / ".draft.tmp").write_bytes(b"\x00\x01")
    before = snapshot(folder)
    with pytest.raises(OutputFolderError) as err:
        claim_folder(folder, "gen")
    msg = str(err.value)
    assert "\n" not in msg and str(folder) in msg
    assert all(name in msg for name in (".draft.tmp", "README.md", "manifest.json"))
    assert snapshot(folder) == before


def test_many_foreign_files_are_summarised_in_one_line(tmp_path):
    for i in range(9):
        (tmp_path / f"f{i}.txt").write_text("x")
    with pytest.raises(OutputFolderError, match=r"f0\.txt, f1\.txt, f2\.txt, f3\.txt, f4\.txt and 4 more"):
        check_folder(tmp_path, "eval")


def test_the_output_of_another_command_is_refused(tmp_path):
    claim_folder(tmp_path / "reports", "eval")
    (tmp_path / "reports" / "summary.md").write_text("x")
    with pytest.raises(OutputFolderError, match="holds the output of 'silpose eval', not of 'silpose gen'"):
        claim_folder(tmp_path / "reports", "gen")


def test_a_recognised_older_output_is_adopted(tmp_path):
    (tmp_path / "headline.json").write_text("{}")
    assert check_folder(tmp_path, "eval", recognise=lambda p: (p / "headline.json").is_file()) == "recognised"
    claim_folder(tmp_path, "eval", recognise=lambda p: (p / "headline.json").is_file())
    assert read_marker(tmp_path)["command"] == "eval"
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "summary.md").write_text("x")
    with pytest.raises(OutputFolderError):
        check_folder(tmp_path / "other", "eval", recognise=lambda p: (p / "headline.json").is_file())


def test_a_marker_silpose_did_not_write_does_not_count(tmp_path):
    (tmp_path / MARKER).write_text(json.dumps({"command": "gen"}))  # no "written_by": "silpose"
    assert read_marker(tmp_path) is None
    with pytest.raises(OutputFolderError):
        check_folder(tmp_path, "gen")


def test_a_file_is_not_a_folder(tmp_path):
    (tmp_path / "x").write_text("x")
    with pytest.raises(OutputFolderError, match="not a folder"):
        claim_folder(tmp_path / "x", "gen")


@pytest.mark.parametrize("where", [".", "..", "../..", "/", "data", "data/..", "data/sub/../.."])
def test_the_working_folder_its_parents_and_the_data_root_are_never_output_folders(where, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "data").mkdir()
    with pytest.raises(OutputFolderError, match="resolves to"):
        check_output_path(where)
    with pytest.raises(OutputFolderError, match="resolves to"):
        claim_folder(where, "gen")
    assert not (tmp_path / MARKER).exists() and not (tmp_path / "data" / MARKER).exists()


def test_the_repository_and_its_parents_are_never_output_folders(tmp_path, monkeypatch):
    repo = repository_root()
    assert repo is not None and (repo / "uv.lock").is_file() and (repo / "shared" / "pyproject.toml").is_file()
    monkeypatch.chdir(tmp_path)  # not the working folder: the repository rule alone refuses
    with pytest.raises(OutputFolderError, match="the silpose repository"):
        check_output_path(repo)
    # a clone under the same parent as the working folder (e.g. both in /tmp) hits that rule first
    with pytest.raises(OutputFolderError, match="the silpose repository|parent of the working folder"):
        check_output_path(repo.parent)
    check_output_path(repo / "data" / "x")  # inside the repository is fine (data/, models/, reports/)


def test_a_symlink_to_the_working_folder_is_refused(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "link").symlink_to(tmp_path)
    with pytest.raises(OutputFolderError, match="the working folder"):
        check_output_path("sub/link")


def test_claim_files_allows_new_files_and_silpose_files_only(tmp_path):
    ours, theirs, new = tmp_path / "a.npz", tmp_path / "b.npz", tmp_path / "c.npz"
    ours.write_bytes(b"silpose")
    theirs.write_bytes(b"user")
    is_ours = lambda p: p.read_bytes() == b"silpose"  # noqa: E731
    assert claim_files([ours, new], "train", recognise=is_ours) == [ours, new]
    with pytest.raises(OutputFolderError) as err:
        claim_files([new, theirs], "train", recognise=is_ours)
    assert "b.npz" in str(err.value) and str(tmp_path) in str(err.value) and "\n" not in str(err.value)
    assert theirs.read_bytes() == b"user" and not new.exists()
    with pytest.raises(OutputFolderError, match="is a folder"):
        claim_files([tmp_path], "train", recognise=is_ours)


def test_silpose_pictures_are_recognised_by_their_png_text(tmp_path):
    """write_figure_atomic tags its PNGs; Pillow (an independent reader) sees the tag, and is_silpose_png
    accepts those and nothing else (another program's PNG, a renamed text file, a truncated PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    from silpose.shared.atomic import FIGURE_SOFTWARE, write_figure_atomic
    from silpose.shared.output_dir import OutputFolderError, claim_picture, is_silpose_png

    ours = write_figure_atomic(plt.figure(figsize=(1, 1)), tmp_path / "ours.png")
    assert Image.open(ours).info.get("Software") == FIGURE_SOFTWARE
    assert is_silpose_png(ours)
    theirs = tmp_path / "theirs.png"
    Image.new("RGB", (4, 4)).save(theirs)
    tagged_other = tmp_path / "other_software.png"
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    info.add_text("Software", "GIMP 2.10")
    Image.new("RGB", (4, 4)).save(tagged_other, pnginfo=info)
    text = tmp_path / "text.png"
    text.write_text("not a picture")
    cut = tmp_path / "cut.png"
    cut.write_bytes(ours.read_bytes()[:20])
    assert not any(is_silpose_png(p) for p in (theirs, tagged_other, text, cut, tmp_path / "missing.png"))
    assert claim_picture(ours, "x") == ours and claim_picture(tmp_path / "new.png", "x") == tmp_path / "new.png"
    for p in (theirs, tmp_path / "new.jpg"):
        with pytest.raises(OutputFolderError):
            claim_picture(p, "x")
