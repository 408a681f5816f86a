"""Camera frames -> joints (``silpose infer --frames``) and its evaluation, without Blender.

A tiny silhouette dataset (``silpose.datagen.testing.synthetic_record``: stick figures, real contour
extraction) and a tiny model; the frames dataset is composited from the test split's TRUE masks
(textured room per camera, cloth-coloured person, floor shadow, noise, flicker;
``benchmarks.frames_composite``) in the frames-dataset layout. References are computed here
independently: background subtraction + contour extraction + ``model.infer`` called by hand, and
IoU counted over pixel coordinate sets.
"""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from silpose.app.recordings.silhouettes import room_view
from silpose.app.recordings.sources import open_recording
from silpose.datagen.testing import synthetic_record
from silpose.model.hypotheses import TEMPORAL_HYPOTHESES, sequence_answer, temporal_choice
from silpose.model.persistence import load_model
from silpose.segment import BackgroundModel, plate_alignment, plate_mismatch_std, warp_plate
from silpose.shared.camera import default_rig
from silpose.shared.cli import build_app
from silpose.shared.contours import EmptyMaskError, extract_contour
from silpose.shared.dataset import load_split, write_shard
from silpose.shared.dataset_schema import build_metadata
from silpose.shared.skeleton import JOINT_NAMES

N_POINTS = 24
N_TEST = 6


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("framesdata") / "tiny"
    root.mkdir()
    rig = default_rig()
    config = {"name": "tiny", "seed": 3, "rig": rig.to_dict(), "n_points": N_POINTS}
    meta = build_metadata(rig.to_dict()["cameras"], config, N_POINTS, generator_version="test")
    for split, n in (("train", 80), ("test", N_TEST)):
        write_shard(root / f"{split}-00000-of-00001.parquet", [synthetic_record(config, split, i) for i in range(n)], meta)
    return root


@pytest.fixture(scope="module")
def model_path(dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("framesmodel") / "tiny.npz"
    res = CliRunner().invoke(build_app(), ["train", str(dataset), "--out", str(out), "-M", "2", "-q", "4",
                                           "--n-init", "1", "--max-iter", "20", "--no-progress"])
    assert res.exit_code == 0, res.output
    return out


@pytest.fixture(scope="module")
def frames_dir(dataset):
    from benchmarks.frames_composite import write_composite_frames

    return write_composite_frames(dataset, dataset / "frames", n_background=10, seed=1)


def load_frames(folder):
    """(N, H, W, 3) uint8 BGR images of a folder in name order, and their names (the reference's own reader)."""
    paths = sorted(folder.glob("*.png"))
    return np.stack([cv2.imread(str(p), cv2.IMREAD_COLOR) for p in paths]), [p.name for p in paths]


def _invoke(*args):
    return CliRunner().invoke(build_app(), [str(a) for a in args])


def _joints(path):
    t = pq.read_table(path).to_pandas()
    return t, np.stack([t[[f"{j}_x", f"{j}_y", f"{j}_z"]].to_numpy() for j in JOINT_NAMES], axis=1)


def _segmenter(frames, rig, cam, bg):
    """The background model ``silpose infer --frames`` fits for camera ``cam``: the empty-room frames ``bg``
    registered to the recording's own view of the room, the camera noise floor raised to their differences from it
    (silpose.app.recordings.silhouettes, background_from_clips)."""
    view = room_view(open_recording(frames / "frames", rig).sources[cam])
    warp = plate_alignment(bg[0], view)
    if warp is not None:
        bg = np.stack([warp_plate(f, warp) for f in bg])
    return BackgroundModel(min_std=max(2.0, plate_mismatch_std(bg[0], view))).fit(bg)


def _reference(model, frames, drop=()):
    """Joints by hand: fit, segment, extract, infer (independent of silpose.app.recordings.one_person)."""
    names = list(model.rig_.names)
    cont = np.full((N_TEST, len(names), N_POINTS, 2), np.nan)
    present = np.zeros((N_TEST, len(names)), bool)
    for k, cam in enumerate(names):
        if cam in drop:
            continue
        bg, _ = load_frames(frames / "background" / cam)
        imgs, _ = load_frames(frames / "frames" / cam)
        masks = _segmenter(frames, model.rig_, cam, bg).segment_batch(imgs)
        for i in range(N_TEST):
            try:
                c = extract_contour(masks[i], N_POINTS)
            except EmptyMaskError:
                continue
            if c.area >= 50:
                cont[i, k], present[i, k] = c.points, True
    # silpose infer --frames: robust inference, 8 hypotheses, the Viterbi choice along the frames
    res = model.infer(cont, present, input_views=range(len(names)), hypotheses=TEMPORAL_HYPOTHESES, robust=True,
                      untangle=True)
    res.hypotheses.chosen = temporal_choice(res.hypotheses, valid=present.any(axis=1))
    return res, present


def test_frames_cli_writes_joints_equal_to_a_hand_made_pipeline(model_path, frames_dir, tmp_path):
    out = tmp_path / "j.parquet"
    # the model's answer as it is (the silhouette fit, on by default, moves joints: tests/app/recordings/test_one_person_room.py)
    res = _invoke("infer", model_path, "--frames", frames_dir, "--out", out, "--contours", "--no-progress",
                  "--no-silhouette-fit")
    assert res.exit_code == 0, res.output
    table, got = _joints(out)
    assert list(table["frame"]) == [f"{i:05d}" for i in range(N_TEST)]
    ref, present = _reference(load_model(model_path), frames_dir)
    assert present.all()
    np.testing.assert_allclose(got, sequence_answer(ref.joints, ref.hypotheses), atol=1e-5)
    seg = json.loads(out.with_name("j.segmentation.json").read_text())
    assert all(s == "ok" for f in seg["frames"] for s in f["status"])
    with np.load(out.with_name("j.contours.npz"), allow_pickle=False) as z:
        assert z["contours_px"].shape == (N_TEST, 4, N_POINTS, 2) and np.isfinite(z["contours_px"]).all()


def test_missing_camera_folder_is_a_missing_view(model_path, frames_dir, tmp_path):
    partial = tmp_path / "partial"
    shutil.copytree(frames_dir, partial)
    shutil.rmtree(partial / "frames" / "cam2")
    out = tmp_path / "j.json"
    res = _invoke("infer", model_path, "--frames", partial, "--out", out, "--no-progress", "--no-silhouette-fit")
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert all(f["views_present"] == ["cam0", "cam1", "cam3"] for f in doc["frames"])
    seg = json.loads(out.with_name("j.segmentation.json").read_text())
    assert seg["counts"]["cam2"]["no video"] == N_TEST and seg["counts"]["cam0"]["ok"] == N_TEST
    ref, _ = _reference(load_model(model_path), partial, drop=("cam2",))
    np.testing.assert_allclose(np.array([f["joints"] for f in doc["frames"]]), sequence_answer(ref.joints, ref.hypotheses),
                               atol=1e-5)


def test_empty_segmentation_is_a_missing_view_for_that_frame(model_path, frames_dir, tmp_path):
    d = tmp_path / "emptyview"
    shutil.copytree(frames_dir, d)
    shutil.copy(d / "background" / "cam1" / "00003.png", d / "frames" / "cam1" / "00002.png")  # nobody there
    out = tmp_path / "j.parquet"
    res = _invoke("infer", model_path, "--frames", d, "--out", out, "--no-progress")
    assert res.exit_code == 0, res.output
    table, got = _joints(out)
    assert table["views_present"][2] == "cam0,cam2,cam3" and np.isfinite(got).all()
    assert (table["n_views_present"].to_numpy() == [4, 4, 3, 4, 4, 4]).all()
    seg = json.loads(out.with_name("j.segmentation.json").read_text())
    assert seg["frames"][2]["status"][1] in ("empty mask", "too small")


def test_overlays_are_written(model_path, frames_dir, tmp_path):
    d = tmp_path / "two"  # two frames keep the test fast
    shutil.copytree(frames_dir, d)
    for cam in (d / "frames").iterdir():
        for p in sorted(cam.glob("*.png"))[2:]:
            p.unlink()
    out = tmp_path / "j.parquet"
    res = _invoke("infer", model_path, "--frames", d, "--out", out, "--overlays", "png", "--no-progress")
    assert res.exit_code == 0, res.output
    pngs = sorted((tmp_path / "j.overlays").glob("*.png"))
    assert [p.stem for p in pngs] == ["00000", "00001"]
    img = cv2.imread(str(pngs[0]))
    assert img is not None and img.shape == (480, 640, 3) and img.std() > 10  # the 4 cameras' 320x240 tiled 2x2


def _broken(frames_dir, tmp_path, how):
    d = tmp_path / how
    shutil.copytree(frames_dir, d)
    if how == "no_background":
        shutil.rmtree(d / "background" / "cam3")
        return d, str(d / "background")
    if how == "one_background_frame":
        for p in sorted((d / "background" / "cam0").glob("*.png"))[1:]:
            p.unlink()
        return d, str(d / "background" / "cam0")
    if how == "size":
        p = d / "frames" / "cam1" / "00004.png"
        cv2.imwrite(str(p), cv2.resize(cv2.imread(str(p)), (300, 240)))
        return d, str(p)
    if how == "count":
        (d / "frames" / "cam2" / "00005.png").unlink()
        return d, str(d / "frames" / "cam2")
    if how == "unreadable":
        p = d / "frames" / "cam0" / "00001.png"
        p.write_bytes(b"not a png")
        return d, str(p)
    if how == "unknown_camera":
        shutil.copytree(d / "frames" / "cam0", d / "frames" / "cam9")
        return d, str(d / "frames" / "cam9")
    if how == "no_frames_folder":
        shutil.rmtree(d / "frames")
        return d, str(d / "frames")
    raise AssertionError(how)


@pytest.mark.parametrize("how, words", [
    ("no_background", "missing background frames for camera 'cam3'"),
    ("one_background_frame", "at least 2 frames"),
    ("size", "frame size 300x240"),
    ("count", "frame files differ"),
    ("unreadable", "cannot read this image"),
    ("unknown_camera", "camera 'cam9' is not in the rig"),
    ("no_frames_folder", "no such folder"),
])
def test_bad_frames_input_gives_a_one_line_error_naming_the_file(model_path, frames_dir, tmp_path, how, words):
    d, names = _broken(frames_dir, tmp_path, how)
    res = _invoke("infer", model_path, "--frames", d, "--out", tmp_path / "j.parquet", "--no-progress")
    assert res.exit_code == 2, res.output
    msg = res.output.strip()
    assert msg.startswith("silpose infer: error:") and "\n" not in msg, msg
    assert names in msg and words in msg, msg
    assert not (tmp_path / "j.parquet").exists()


def test_video_input(model_path, frames_dir, tmp_path):
    d = tmp_path / "video"
    shutil.copytree(frames_dir, d)
    cam = "cam0"
    imgs, _ = load_frames(d / "frames" / cam)
    shutil.rmtree(d / "frames" / cam)
    writer = cv2.VideoWriter(str(d / "frames" / f"{cam}.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10,
                             (imgs.shape[2], imgs.shape[1]))
    if not writer.isOpened():
        pytest.skip("OpenCV cannot write MJPG .avi here")
    for img in imgs:
        writer.write(img)
    writer.release()
    out = tmp_path / "j.json"
    res = _invoke("infer", model_path, "--frames", d, "--out", out, "--no-progress")
    assert res.exit_code == 0, res.output
    assert len(json.loads(out.read_text())["frames"]) == N_TEST
    short = tmp_path / "short"
    shutil.copytree(d, short)
    (short / "frames" / "cam1" / "00005.png").unlink()
    for f in (short / "frames").iterdir():
        if f.is_dir():
            (f / "00005.png").unlink(missing_ok=True)
    res = _invoke("infer", model_path, "--frames", short, "--out", tmp_path / "k.json", "--no-progress")
    assert res.exit_code == 2 and "frame counts differ" in res.output and "cam0.avi: 6" in res.output, res.output


def _iou_brute(pred, true):
    p = set(zip(*np.nonzero(pred)))
    t = set(zip(*np.nonzero(true)))
    return len(p & t) / len(p | t)


def test_frames_evaluation_iou_and_errors(model_path, frames_dir, tmp_path):
    from silpose.eval.frames_eval import write_frames_report

    model = load_model(model_path)
    ev, written = write_frames_report(frames_dir, model, tmp_path / "rep")
    truth = load_split(frames_dir, "test", with_masks=True)
    for k, cam in enumerate(model.rig_.names):
        bg, _ = load_frames(frames_dir / "background" / cam)
        imgs, _ = load_frames(frames_dir / "frames" / cam)
        masks = _segmenter(frames_dir, model.rig_, cam, bg).segment_batch(imgs)
        ref = [_iou_brute(masks[i], truth.masks[i, k]) for i in range(N_TEST)]
        np.testing.assert_allclose(ev["iou"][:, k], ref, rtol=0, atol=1e-12)
    assert np.mean(ev["iou"]) >= 0.9  # the bar for segmented masks
    # pose errors from true silhouettes: the model's own inference on the truth contours
    from silpose.shared.metrics import pose_error_cm

    ref_true = pose_error_cm(model.infer(truth.contours).joints, truth.joints)
    np.testing.assert_allclose(ev["pose_cm"]["true"], ref_true)
    assert np.isfinite(ev["pose_cm"]["segmented"]).all() and np.isfinite(ev["chamfer_px"]["segmented"]).all()
    md = written["frames_summary"].read_text().splitlines()
    all_iou = ev["iou"].ravel()
    q1, med, q3 = np.percentile(all_iou, [25, 50, 75])
    assert f"| all cameras | {all_iou.size} | {all_iou.mean():.2f} | {med:.2f} | {q1:.2f} | {q3:.2f} |" in md
    table = pq.read_table(written["frames_results"]).to_pandas()
    assert len(table) == 2 * N_TEST
    for key in ("segmented", "true"):
        rows = table[table["input"] == key].set_index("sample_id").loc[truth.sample_id]
        np.testing.assert_array_equal(rows["pose_cm"].to_numpy(), ev["pose_cm"][key])
    seg = table[table["input"] == "segmented"].set_index("sample_id").loc[truth.sample_id]
    np.testing.assert_array_equal(seg[[f"iou_{c}" for c in model.rig_.names]].to_numpy(), ev["iou"])
    for key in ("frames_errors", "frames_example"):
        img = cv2.imread(str(written[key]))
        assert img is not None and img.shape[0] > 200 and img.std() > 10, key  # a real, non-blank figure


def test_eval_hook_runs_when_frames_exist_and_notes_a_skip(model_path, frames_dir, dataset, tmp_path):
    from types import SimpleNamespace

    from silpose.eval.run import EvalInputError, frames_section

    model = load_model(model_path)
    ev = SimpleNamespace(notes=[], timings={})
    written = frames_section(ev, model, dataset, tmp_path / "a", None, None)  # dataset/frames exists
    assert "frames_summary" in written and ev.notes[0].startswith("camera frames (frames.md): mean mask IoU")
    ev = SimpleNamespace(notes=[], timings={})
    assert frames_section(ev, model, tmp_path, tmp_path / "b", None, None) == {}
    assert "skipped" in ev.notes[0] and not (tmp_path / "b").exists()
    assert frames_section(ev, model, dataset, tmp_path / "c", False, None) == {}
    with pytest.raises(EvalInputError, match="not found"):
        frames_section(ev, model, dataset, tmp_path / "d", tmp_path / "nowhere", None)
