"""Camera image sizes have an upper bound (issue 13: a 100000x80000 rig was accepted and generation died
allocating 29.8 GiB for one sample's masks)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from silpose.shared.camera import Camera, RigError, default_rig, load_rig
from silpose.shared.cli import build_app
from silpose.shared.pinhole import MAX_IMAGE_SIDE


def camera(width, height):
    return Camera(name="camX", K=np.diag([400.0, 400.0, 1.0]), R=np.eye(3), t=[0, 0, 5.0], width=width, height=height)


@pytest.mark.parametrize("size", [(100_000, 80_000), (MAX_IMAGE_SIDE + 1, 240), (320, MAX_IMAGE_SIDE + 1)])
def test_oversized_images_are_refused_naming_the_camera_and_the_limit(size):
    with pytest.raises(RigError, match=rf"camera 'camX' fields width/height: must be in 1\.\.{MAX_IMAGE_SIDE} px"):
        camera(*size)


def test_the_limit_admits_8k_video():
    assert MAX_IMAGE_SIDE >= 7680
    cam = camera(7680, 4320)
    assert (cam.width, cam.height) == (7680, 4320)


def _big_rig_file(path):
    rig = default_rig().to_dict()
    for c in rig["cameras"]:
        c["width"], c["height"] = 100_000, 80_000
    path.write_text(json.dumps(rig))
    return path


def test_a_rig_file_with_huge_images_is_refused_by_the_loader_and_by_gen(tmp_path):
    rig = _big_rig_file(tmp_path / "big.json")
    with pytest.raises(RigError, match="width/height"):
        load_rig(rig)
    res = CliRunner().invoke(build_app(), ["gen", "smoke", "--rig", str(rig), "--out", str(tmp_path / "ds"),
                                           "--no-progress"])
    assert res.exit_code == 2
    line = [l for l in res.output.splitlines() if l.startswith("silpose gen: error:")]
    # the error names the rig file it came from (issue 10) and the limit
    assert len(line) == 1 and "big.json" in line[0] and f"1..{MAX_IMAGE_SIDE} px" in line[0]
    assert not (tmp_path / "ds").exists()
