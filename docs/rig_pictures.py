"""Draw docs/images/rig_show_default.png and docs/images/rig_show_lab.png with ``silpose rig``.

The default rig is the built-in one (``silpose.shared.camera.default_rig``) written as a rig file.
The lab is the issue's: four cameras along one wall of a 6 m x 8 m room, 2 m up, calibrated in
millimetres against a board on the floor (z into the floor, origin at a board corner), one OpenCV
file per camera spelled as two real recordings spelled them (``silpose.app.rig.examples``), no image
size in the files. Both go through the commands a user runs. Run: ``.venv/bin/python docs/rig_pictures.py``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from typer.testing import CliRunner

from silpose.app.rig.examples import one_wall_lab
from silpose.app.rig.opencv import write_opencv_camera
from silpose.shared.camera import default_rig
from silpose.shared.cli import build_app

ROOT = Path(__file__).resolve().parents[1]
IMAGES = ROOT / "docs" / "images"
#: The issue's two spellings: calibrateCamera's output names, and CamelCase names (matrix + vector).
SPELLINGS = [
    {"K": "camera_matrix", "dist": "distortion_coefficients", "rvec": "rotation_vectors", "t": "translation_vectors"},
    {"K": "CameraMatrix", "dist": "DistortionCoeffs", "R": "Rotation", "rvec": "RVector", "t": "TVector"},
]


def run(*args: str) -> str:
    result = CliRunner().invoke(build_app(), list(args))
    if result.exit_code != 0:
        raise SystemExit(result.output)
    return result.output


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="silpose-rig-pictures-") as tmp:
        tmp = Path(tmp)
        default = tmp / "default_rig.json"
        default.write_text(default_rig().to_json())
        print(run("rig", "show", str(default), "--out", str(IMAGES / "rig_show_default.png")))
        calib, _ = one_wall_lab()
        files = []
        for i, c in enumerate(calib):
            p = tmp / "lab" / f"{c.name}{'.xml' if i < 2 else '.yml'}"
            p.parent.mkdir(exist_ok=True)
            write_opencv_camera(p, c, keys={**{k: None for k in ("rvec", "R", "width", "height")}, **SPELLINGS[i // 2]},
                                rotation="both")
            files.append(str(p))
        lab = tmp / "lab_rig.json"
        print(run("rig", "import", *files, "--unit", "mm", "--image-size", "644x486", "--out", str(lab)))
        print(run("rig", "show", str(lab), "--out", str(IMAGES / "rig_show_lab.png")))


if __name__ == "__main__":
    main()
