"""End to end through fisheye lenses: the lab's two walkers recorded by cameras with OpenCV fisheye lenses
(wider than the lab's own), a small model of that rig trained by the real generator and trainer, and
``silpose infer --videos --masks``, scored against the truth as the lab's own recording is (``test_lab.py``)."""

import numpy as np
import pytest
from typer.testing import CliRunner

from benchmarks.recording_scores import (clean_reference, joints_inside, read_rows, read_view_status, score_reference,
                                         score_rows)
from silpose.datagen.lab import lab_rig, make_lab_recording, unpack_masks
from silpose.model.persistence import load_model
from silpose.shared.camera import Camera, Rig
from silpose.shared.cli import build_app

from .conftest import LAB_FRAMES, train_small_model

pytestmark = pytest.mark.blender

#: cm the world-frame error may exceed the clean per-person masks' (test_lab.WORLD_MARGIN_CM)
WORLD_MARGIN_CM = 3.0


def fisheye_rig() -> Rig:
    """The lab's cameras with wider lenses (focal 380 px), each an OpenCV fisheye (k1 0.06-0.096)."""
    lens = np.array([0.06, -0.02, 0.004, 0.0])
    return Rig(tuple(Camera(c.name, c.K, c.R, c.t, c.width, c.height, lens * (1 + 0.2 * i), fisheye=True)
                     for i, c in enumerate(lab_rig(focal_px=380.0))))


@pytest.fixture(scope="module")
def fisheye_lab(tmp_path_factory):
    rig = fisheye_rig()
    rec = make_lab_recording(tmp_path_factory.mktemp("fishlab") / "lab", n_frames=LAB_FRAMES, rig=rig)
    return rec, train_small_model(tmp_path_factory.mktemp("fishdata"), rig)


def test_two_walkers_through_fisheye_lenses(fisheye_lab, tmp_path):
    """Measured (50 frames; M 3 q 12 on 240 walkers of the fisheye rig, :func:`.conftest.train_small_model`): 2
    people, no identity switch, 98 of 100 person-frames with joints, world-frame error 9.4 cm against 10.0 from the
    clean per-person masks, 0.998 of the joints inside their own silhouettes."""
    rec, model = fisheye_lab
    assert not (rec / "calibration").exists() and load_model(model).rig_[0].fisheye
    res = CliRunner().invoke(build_app(), ["infer", str(model), "--videos", str(rec / "masks"), "--masks", "--out",
                                           str(tmp_path / "out"), "--no-progress", "--overlays", "none"])
    assert res.exit_code == 0, res.output
    truth = np.load(rec / "truth.npz")
    masks = unpack_masks(truth)
    rows = read_rows(tmp_path / "out" / "joints.parquet")
    scores = score_rows(rows, truth["joints"])
    reference = score_reference(clean_reference(load_model(model), masks), truth["joints"])
    inside = joints_inside(rows, read_view_status(tmp_path / "out" / "joints.parquet"), scores["per_row"]["paired"],
                           masks, list(load_model(model).rig_))
    print("fisheye lab", {k: v for k, v in scores.items() if k != "per_row"}, "clean", reference, "inside", inside)
    assert scores["persons"] == 2 and scores["identity_switches"] == 0
    assert scores["with_joints"] >= 0.9 * scores["paired"]
    assert scores["world_error_cm"] <= reference["world_error_cm"] + WORLD_MARGIN_CM
    assert inside["share"] >= 0.95
