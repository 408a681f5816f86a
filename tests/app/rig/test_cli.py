"""``silpose rig import`` / ``silpose rig show`` as a user runs them, and the issue's done-when check:
per-camera OpenCV files of the one-wall lab spelled as in the issue, imported with only
``--unit mm --image-size 644x486``, give an automatic workspace of at least 2 m x 2 m, and
``silpose gen --rig`` on the rig yields a dataset that ``silpose validate`` passes."""

from __future__ import annotations

import json
import subprocess
import sys

import cv2
import numpy as np
from typer.testing import CliRunner

from silpose.app.rig.examples import one_wall_lab
from silpose.app.rig.opencv import write_opencv_camera
from silpose.shared.camera import default_rig, load_rig
from silpose.shared.cli import build_app

#: The issue's two recordings of the lab: calibrateCamera's output names, and CamelCase names.
WHY_SPELLINGS = [
    {"K": "camera_matrix", "dist": "distortion_coefficients", "rvec": "rotation_vectors", "t": "translation_vectors"},
    {"K": "CameraMatrix", "dist": "DistortionCoeffs", "R": "Rotation", "rvec": "RVector", "t": "TVector"},
]


def write_lab(folder) -> list:
    """cam1.xml, cam2.xml (first spelling), cam3.yml, cam4.yml (second: Rotation matrix + RVector)."""
    folder.mkdir(parents=True, exist_ok=True)
    calib, _ = one_wall_lab()
    paths = []
    for i, c in enumerate(calib):
        spelling = WHY_SPELLINGS[i // 2]
        p = folder / f"{c.name}{'.xml' if i < 2 else '.yml'}"
        write_opencv_camera(p, c, keys={**{k: None for k in ("rvec", "R", "width", "height")}, **spelling},
                            rotation="both")
        paths.append(p)
    assert "rotation_vectors" in paths[0].read_text() and "RVector" in paths[3].read_text()
    assert "image_width" not in paths[0].read_text()  # no image size in the files
    return paths


def run(*args):
    return CliRunner().invoke(build_app(), [str(a) for a in args])


def silpose(*args, timeout=900):
    return subprocess.run([sys.executable, "-m", "silpose.shared.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


def test_import_prints_its_decisions_and_show_draws_the_rig(tmp_path):
    paths = write_lab(tmp_path / "lab")
    out = tmp_path / "rig.json"
    r = run("rig", "import", *paths, "--unit", "mm", "--image-size", "644x486", "--out", out, "--step", "0.2")
    assert r.exit_code == 0, r.output
    for words in ("up: -z of the calibration", "floor: the calibration plane z = 0", "origin: calibration point",
                  "workspace: ", "cam1", "cam4", f"wrote {out}"):
        assert words in r.output, words
    rig = load_rig(out)
    assert rig.names == ("cam1", "cam2", "cam3", "cam4") and rig.source == str(out)
    assert json.loads(out.read_text())["source"] == ", ".join(map(str, paths))
    png = tmp_path / "pics" / "rig.png"
    r = run("rig", "show", out, "--out", png)
    assert r.exit_code == 0, r.output
    assert "centre x, y, z (m)" in r.output and "workspace: " in r.output and "calibration frame -> silpose" in r.output
    assert f"imported from {paths[0]}" in r.output
    img = cv2.imread(str(png))
    assert img is not None and img.shape[1] > 1000 and img.std() > 10


def test_rig_show_of_the_default_rig_and_errors(tmp_path):
    rig = tmp_path / "default.json"
    rig.write_text(default_rig().to_json())
    r = run("rig", "show", rig)
    assert r.exit_code == 0 and "identity transform" in r.output
    assert "3.00 m x 3.00 m centred at (0.00, 0.00) m" in r.output
    assert r.output.count(" yes ") == 4  # every camera sees the workspace up to 2 m
    r = run("rig", "show", tmp_path / "cam1.xml")
    assert r.exit_code == 2
    r = run("rig", "import", tmp_path / "nope.yml", "--out", tmp_path / "x.json")
    assert r.exit_code == 2 and not (tmp_path / "x.json").exists()


def test_error_lines_of_the_commands(tmp_path):
    bad = tmp_path / "cam1.yml"
    bad.write_text("%YAML:1.0\ncamera_matrix: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n")
    r = silpose("rig", "import", bad, "--out", tmp_path / "rig.json", timeout=120)
    lines = [line for line in r.stderr.splitlines() if line.startswith("silpose rig import: error: ")]
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith(f"silpose rig import: error: {bad}: missing field rotation")
    r = silpose("gen", "smoke", "--rig", bad, "--out", tmp_path / "ds", timeout=120)
    lines = [line for line in r.stderr.splitlines() if line.startswith("silpose gen: error: ")]
    assert len(lines) == 1 and f"{bad}: a calibration file, not a silpose rig" in lines[0]
    assert f"silpose rig import {bad}" in lines[0]


TINY = """name = "tiny"
seed = 5
renderer = "raster"
shard_size = 4
n_points = 200
max_redraws = 50
[splits]
train = 8
test = 4
"""


def test_done_when_lab_files_import_with_unit_and_image_size_only_then_gen_and_validate(tmp_path):
    paths = write_lab(tmp_path / "lab")
    rig_file = tmp_path / "rig.json"
    r = silpose("rig", "import", *paths, "--unit", "mm", "--image-size", "644x486", "--out", rig_file, timeout=300)
    assert r.returncode == 0, r.stderr
    rig = load_rig(rig_file)
    assert rig.workspace.size.min() >= 2.0, rig.workspace.describe()
    cfg = tmp_path / "tiny.toml"
    cfg.write_text(TINY)
    ds = tmp_path / "ds"
    r = silpose("gen", cfg, "--rig", rig_file, "--out", ds, "--workers", "2", "--no-progress")
    assert r.returncode == 0, r.stderr
    r = silpose("validate", ds, timeout=300)
    assert r.returncode == 0 and "OK: no problems found" in r.stdout, r.stdout + r.stderr
    from silpose.shared.dataset import load_split

    for split in ("train", "test"):
        data = load_split(ds, split)
        assert data.rig.transform.to_dict() == rig.transform.to_dict()
        assert data.rig.workspace.to_dict() == rig.workspace.to_dict()
        xy = np.stack([data.gait["x"], data.gait["y"]], axis=1)
        assert rig.workspace.contains(xy.astype(np.float64)).all()
        # the joints come back in the lab's own frame (mm, z into the floor) through the stored transform
        lab = data.rig.transform.to_calibration(data.joints.astype(np.float64))
        assert np.all(lab[..., 2] < 1.0) and np.all(lab[..., 2] > -2100)  # z down: the body above the floor
    card = (ds / "README.md").read_text()
    assert f"**workspace** (walkers' pelvis positions, uniform): {rig.workspace.describe()}" in card
    assert "calibration frame -> world frame" in card and "scale 0.001 m per calibration unit" in card


def test_outputs_never_replace_a_file_silpose_did_not_write(tmp_path):
    """Nothing lost: --out naming a calibration file, a user's JSON or a user's picture is refused before any
    work, the file left byte for byte; silpose's own rig file and picture are replaced on a rerun."""
    paths = write_lab(tmp_path / "lab")
    before = paths[0].read_bytes()
    args = (*paths, "--unit", "mm", "--image-size", "644x486", "--step", "0.2")
    r = run("rig", "import", *args, "--out", paths[0])
    assert r.exit_code != 0 and "names one of the calibration files" in r.output
    assert paths[0].read_bytes() == before
    notes = tmp_path / "notes.json"
    notes.write_text('{"my": "notes"}')
    r = run("rig", "import", *args, "--out", notes)
    assert r.exit_code != 0 and "which silpose did not write" in r.output and notes.read_text() == '{"my": "notes"}'
    photo = tmp_path / "photo.png"
    cv2.imwrite(str(photo), np.full((8, 8, 3), 200, np.uint8))
    photo_bytes = photo.read_bytes()
    out = tmp_path / "rig.json"
    r = run("rig", "import", *args, "--out", out, "--show", photo)
    assert r.exit_code != 0 and "photo.png" in r.output and not out.exists()
    r = run("rig", "show", default_rig_file(tmp_path), "--out", photo)
    assert r.exit_code != 0 and photo.read_bytes() == photo_bytes
    r = run("rig", "show", default_rig_file(tmp_path), "--out", tmp_path / "rig.jpg")
    assert r.exit_code != 0 and ".png" in r.output

    pic = tmp_path / "rig.png"
    for _ in range(2):  # the second run replaces silpose's own outputs
        r = run("rig", "import", *args, "--out", out, "--show", pic)
        assert r.exit_code == 0, r.output
    r = run("rig", "show", out, "--out", pic)
    assert r.exit_code == 0, r.output


def default_rig_file(folder):
    p = folder / "default.json"
    p.write_text(default_rig().to_json())
    return p
