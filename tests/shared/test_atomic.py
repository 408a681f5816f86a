"""silpose.shared.atomic: the final name holds the old content or the new, never a partial file."""

import json

import pytest

from silpose.shared.atomic import (atomic_open, atomic_path, tmp_name, write_figure_atomic, write_json_atomic,
                                   write_text_atomic)


def test_write_then_read_back(tmp_path):
    p = write_json_atomic(tmp_path / "sub" / "a.json", {"x": [1, 2]})
    assert json.loads(p.read_text()) == {"x": [1, 2]}
    assert [f.name for f in p.parent.iterdir()] == ["a.json"]


def test_failure_keeps_previous_version_and_leaves_no_temporary(tmp_path):
    p = tmp_path / "a.txt"
    write_text_atomic(p, "old")
    with pytest.raises(RuntimeError):
        with atomic_open(p, "w") as f:
            f.write("half of the new")
            raise RuntimeError("killed mid-write")
    assert p.read_text() == "old"
    assert sorted(f.name for f in tmp_path.iterdir()) == ["a.txt"]


def test_temporary_name_is_hidden_and_matches_cleanup_glob(tmp_path):
    t = tmp_name(tmp_path / "train-00000-of-00001.parquet")
    assert t.name.startswith(".") and t.match(".*.tmp")


def test_writer_that_creates_nothing_is_an_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        with atomic_path(tmp_path / "never.bin"):
            pass
    assert not (tmp_path / "never.bin").exists()


def test_read_only_mode_refused(tmp_path):
    with pytest.raises(ValueError):
        with atomic_open(tmp_path / "x", "r"):
            pass


def test_write_figure_atomic_saves_a_png_closes_the_figure_and_leaves_nothing_on_failure(tmp_path):
    import cv2
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(2, 1))
    ax.plot([0, 1], [0, 1])
    out = write_figure_atomic(fig, tmp_path / "a.png", dpi=50)
    img = cv2.imread(str(out))
    assert img is not None and img.shape == (50, 100, 3)  # 2 x 1 inches at 50 dpi
    assert fig.number not in plt.get_fignums()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]

    broken = plt.figure()

    def savefig(path, **kwargs):  # a writer that dies half-way
        open(path, "wb").write(b"half a png")
        raise OSError("disk full")

    broken.savefig = savefig
    with pytest.raises(OSError, match="disk full"):
        write_figure_atomic(broken, tmp_path / "b.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]  # no b.png, no temporary file
    assert broken.number not in plt.get_fignums()  # closed all the same
