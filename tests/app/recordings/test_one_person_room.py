"""One person (``silpose infer --people 1``) put in the room: the root placed by the views alone, the silhouette fit.

Input: the first walker of the generated lab recording alone, as lossless mask frames (its own clean masks from
``truth.npz``), and the small lab-rig model. References, independent of the one-person code: the true joints; the
several-people pipeline on the same frames, which places the root with the floor grid's position as its prior; the
true masks (``benchmarks.recording_scores.joints_inside``); and the rig's transform applied to the written joints.
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from benchmarks.recording_scores import joints_inside, read_rows, score_rows
from silpose.app.recordings.one_person import run_one_person
from silpose.app.recordings.pipeline import RecordingOptions, run_recording
from silpose.datagen.lab import LAB_TRANSFORM, unpack_masks
from silpose.model.persistence import load_model, save_model
from silpose.shared.cli import build_app
from silpose.shared.skeleton import JOINT_NAMES

pytestmark = pytest.mark.blender

#: frames of the walker used (of the lab recording's)
FRAMES = 40


@pytest.fixture(scope="module")
def walker(lab, tmp_path_factory):
    """(folder of mask frames <camera>/<frame>.png of walker 0 alone, its true joints (T, 19, 3), its masks
    (T, 1, K, H, W))."""
    t = np.load(lab / "truth.npz")
    masks = unpack_masks(t)[:FRAMES, :1]
    folder = tmp_path_factory.mktemp("one") / "masks"
    for k, cam in enumerate(t["cameras"]):
        (folder / str(cam)).mkdir(parents=True)
        for i in range(FRAMES):
            cv2.imwrite(str(folder / str(cam) / f"{i:05d}.png"), masks[i, 0, k].astype(np.uint8) * 255)
    return folder, t["joints"][:FRAMES, 0], masks


@pytest.fixture(scope="module")
def placed(walker, lab_model):
    """run_one_person with and without the silhouette fit."""
    return {fit: run_one_person(str(lab_model), walker[0], RecordingOptions(masks=True, overlays=False,
                                                                           silhouette_fit=fit))
            for fit in (False, True)}


def _inside(fr, masks, cameras) -> float:
    world = fr.joints_world
    ok = np.isfinite(world).all(axis=(1, 2))
    rows = {"frame": np.arange(len(world)), "status": np.where(ok, "ok", "no usable view"), "joints": world}
    status = np.where(fr.present, "ok", "missing")
    return joints_inside(rows, status, np.zeros(len(world), int), masks, cameras)["share"]


def test_root_placed_by_the_views_as_the_floor_grid_places_it(placed, walker, lab_model, tmp_path):
    """Without a floor grid the root is where the several-people pipeline (floor grid prior) puts it on the same
    frames, and near the truth. Measured here (40 frames, the small model): 0.26 cm from the pipeline's root on
    average, 9.17 cm from the true pelvis (the pipeline's 9.11 cm)."""
    _, truth, _ = walker
    fr = placed[False]
    world = fr.joints_world
    ok = np.isfinite(world).all(axis=(1, 2))
    assert ok.sum() >= FRAMES - 2
    out = tmp_path / "several"
    run_recording(str(lab_model), walker[0], out, RecordingOptions(masks=True, overlays=False, silhouette_fit=False))
    rows = read_rows(out / "joints.parquet")
    sc = score_rows(rows, truth[:, None])
    mine = np.linalg.norm(world[ok, 0] - truth[ok, 0], axis=1).mean() * 100
    both = [(int(f), r) for f, r, s in zip(rows["frame"], rows["joints"], rows["status"]) if s == "ok" and ok[int(f)]]
    apart = np.mean([np.linalg.norm(world[f, 0] - r[0]) for f, r in both]) * 100
    print("root vs truth cm", mine, "pipeline", sc["root_error_cm"], "apart", apart, "rows", len(both))
    assert len(both) >= FRAMES - 5
    assert apart < 3.0
    assert mine < sc["root_error_cm"] + 2.0 and mine < 12.0
    # the model's root-relative answer is kept: the placement moved the skeleton as a whole
    rel = world[ok] - world[ok, :1]
    from silpose.model.hypotheses import single_answer

    answer = single_answer(fr.result.joints, fr.result.hypotheses)[ok]
    assert np.allclose(rel, answer - answer[:, :1], atol=1e-9)


def test_silhouette_fit_moves_joints_inside_the_views_used(placed, walker, lab_model):
    """Measured here: 0.879 -> 0.997 of the joints inside the walker's own mask (2 px) in the views used; world
    error 9.62 -> 9.01 cm."""
    _, truth, masks = walker
    cameras = list(load_model(lab_model).rig_)
    before, after = _inside(placed[False], masks, cameras), _inside(placed[True], masks, cameras)

    def world_cm(fr):
        ok = np.isfinite(fr.joints_world).all(axis=(1, 2))
        return np.linalg.norm(fr.joints_world[ok] - truth[ok], axis=2).mean() * 100

    print("inside", before, "->", after, "world cm", world_cm(placed[False]), "->", world_cm(placed[True]))
    assert after >= 0.97 and after >= before + 0.01
    assert world_cm(placed[True]) <= world_cm(placed[False]) + 0.2


@pytest.mark.parametrize("suffix", [".parquet", ".json"])
def test_joints_file_holds_the_root_and_the_calibration_frame(walker, lab_model, tmp_path, suffix):
    """The file's root-relative joints plus its root, through the rig's transform (the lab's: mm, z down), are its
    calibration-frame joints; the root is the placed pelvis."""
    model = load_model(lab_model)
    object.__setattr__(model.rig_, "transform", LAB_TRANSFORM)
    path = tmp_path / "lab.npz"
    save_model(path, model)
    out = tmp_path / f"joints{suffix}"
    res = CliRunner().invoke(build_app(), ["infer", str(path), "--videos", str(walker[0]), "--masks", "--people", "1",
                                           "--out", str(out), "--no-progress", "--no-silhouette-fit"])
    assert res.exit_code == 0, res.output
    if suffix == ".parquet":
        t = pq.read_table(out)
        meta = json.loads(t.schema.metadata[b"silpose_infer"])
        rel = np.stack([[t.column(f"{j}_{a}").to_numpy() for a in "xyz"] for j in JOINT_NAMES]).transpose(2, 0, 1)
        root = np.stack([t.column(f"root_{a}").to_numpy() for a in "xyz"], axis=1)
        cal = np.stack([[t.column(f"{j}_cal_{a}").to_numpy() for a in "xyz"] for j in JOINT_NAMES]).transpose(2, 0, 1)
    else:
        doc = json.loads(out.read_text())
        meta = doc
        frames = [f for f in doc["frames"] if f["root"] is not None]
        assert len(frames) >= FRAMES - 2
        rel = np.array([f["joints"] for f in frames])
        root = np.array([f["root"] for f in frames])
        cal = np.array([f["joints_calibration"] for f in frames])
    assert meta["transform"]["scale"] == 0.001 and "root_x" in meta["root_units"]
    ok = np.isfinite(root).all(axis=1)
    assert ok.sum() >= FRAMES - 2
    world = rel[ok] + root[ok, None]
    assert np.allclose(rel[ok, 0], 0.0, atol=1e-6)  # the root is the pelvis
    assert np.allclose(cal[ok], LAB_TRANSFORM.to_calibration(world.reshape(-1, 3)).reshape(world.shape), atol=0.5)
    assert (cal[ok][..., 2] < 50).all() and (cal[ok][..., 2] > -2200).all()  # mm, z down: above the floor
    assert np.allclose(world[:, 0], walker[1][ok, 0], atol=0.2)  # metres: the true pelvis
    if suffix == ".parquet":  # silpose export reads the placed joints, in either frame
        from silpose.app.export.motion import read_motion

        room, lab_frame = read_motion(out, "silpose"), read_motion(out, "calibration")
        assert not room.root_relative and room.units == "m" and lab_frame.units == "mm"
        assert np.allclose(room.joints[ok], world, atol=1e-5)
        assert np.allclose(lab_frame.joints[ok], cal[ok])
