"""One camera pipeline, one person (``silpose infer --people 1``; ``--frames DIR`` is its alias for a frames folder).

Cylinder "people" in the default rig (320x240 cameras, no Blender) and a tiny model of it (joints meaningless): a
frames folder of colour frames composited over a textured room (``silpose.segment.composite``), and lossless mask
frames. References are computed here, independently of
``silpose.app.recordings``: background subtraction, the largest blob's contour (``extract_contour``) and
``model.infer`` called by hand.
"""

import json

import cv2
import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from silpose.app.recordings.one_person import run_one_person
from silpose.app.recordings.pipeline import RecordingOptions, run_recording
from silpose.app.recordings.resolution import min_blob_area, work_size
from silpose.app.recordings.silhouettes import binarise, room_view
from silpose.app.recordings.sources import open_recording
from silpose.model.hypotheses import TEMPORAL_HYPOTHESES, sequence_answer, temporal_choice
from silpose.segment import BackgroundModel, plate_alignment, plate_mismatch_std, warp_plate
from silpose.datagen.testing import synthetic_record
from silpose.model import ShapeStructureModel
from silpose.model.persistence import load_model, save_model
from silpose.shared.camera import default_rig
from silpose.shared.cli import build_app
from silpose.shared.contours import extract_contour
from silpose.shared.skeleton import JOINT_NAMES

N = 3  # frames


def _invoke(*args):
    return CliRunner().invoke(build_app(), [str(a) for a in args])


def _write(folder, frames) -> None:
    folder.mkdir(parents=True)
    for i, f in enumerate(frames):
        cv2.imwrite(str(folder / f"{i:05d}.png"), f)


@pytest.fixture(scope="module")
def rig():
    return default_rig()


@pytest.fixture(scope="module")
def tiny_model(rig):
    """A 2-component model of the default rig fitted on 60 stick-figure records."""
    config = {"seed": 5, "rig": rig.to_dict(), "n_points": 40}
    recs = [synthetic_record(config, "train", i) for i in range(60)]
    return ShapeStructureModel(2, 4, n_init=1, max_iter=30).fit(np.stack([r["contours"] for r in recs]),
                                                                 np.stack([r["joints"] for r in recs]), rig=rig)


@pytest.fixture(scope="module")
def tiny_model_file(tiny_model, tmp_path_factory):
    path = tmp_path_factory.mktemp("one-model") / "tiny.npz"
    save_model(path, tiny_model)
    return path


@pytest.fixture(scope="module")
def frames_folder(rig, tools, tmp_path_factory):
    """DIR/frames/<camera>/0000i.png (a cylinder walking, composited in colour) and DIR/background/<camera>/."""
    from silpose.segment.composite import background_frames, composite_frame, room

    root = tmp_path_factory.mktemp("one") / "frames_folder"
    where = tools.walk((-0.6, 0.0), (0.6, 0.3), N)
    masks = np.stack([tools.cylinder_masks(rig, [p]) for p in where], 1)  # (K, N, H, W)
    for k, cam in enumerate(rig):
        size = (cam.width, cam.height)
        clean = room(k, size)
        _write(root / "frames" / cam.name, [composite_frame(masks[k, i] > 0, k, i, clean=clean) for i in range(N)])
        _write(root / "background" / cam.name, background_frames(k, size, 3))
    return root


def _joints(path):
    t = pq.read_table(path).to_pandas()
    return t, np.stack([t[[f"{j}_x", f"{j}_y", f"{j}_z"]].to_numpy() for j in JOINT_NAMES], axis=1)


def test_frames_alias_equals_a_hand_made_pipeline(tiny_model, tiny_model_file, frames_folder, rig, tmp_path):
    out = tmp_path / "j.parquet"
    res = _invoke("infer", tiny_model_file, "--frames", frames_folder, "--out", out, "--no-progress")
    assert res.exit_code == 0, res.output
    table, got = _joints(out)
    assert list(table["frame"]) == [f"{i:05d}" for i in range(N)]
    n_pts = tiny_model.layout_.n_points
    cont = np.full((N, len(rig), n_pts, 2), np.nan)
    sources = open_recording(frames_folder / "frames", rig).sources
    for k, cam in enumerate(rig):
        read = lambda sub: np.stack([cv2.imread(str(p)) for p in sorted((frames_folder / sub / cam.name).glob("*.png"))])  # noqa: E731
        # the empty-room frames registered to the recording's own view of the room, and the camera noise floor
        # raised to their differences from it (silpose.app.recordings.silhouettes, background_from_clips)
        plate, view = read("background"), room_view(sources[cam.name])
        warp = plate_alignment(plate[0], view)
        if warp is not None:
            plate = np.stack([warp_plate(f, warp) for f in plate])
        model = BackgroundModel(min_std=max(2.0, plate_mismatch_std(plate[0], view)))
        masks = model.fit(plate).segment_batch(read("frames"))
        for i in range(N):
            c = extract_contour(masks[i], n_pts)
            assert c.area >= min_blob_area(cam, cam, rig.workspace.center)
            cont[i, k] = c.points
    present = np.ones((N, len(rig)), bool)
    ref = tiny_model.infer(cont, present, input_views=range(len(rig)), hypotheses=TEMPORAL_HYPOTHESES, robust=True,
                           untangle=True)
    ref.hypotheses.chosen = temporal_choice(ref.hypotheses, valid=present.any(axis=1))
    np.testing.assert_allclose(got, sequence_answer(ref.joints, ref.hypotheses), atol=1e-5)
    seg = json.loads(out.with_name("j.segmentation.json").read_text())
    assert seg["counts"]["cam0"]["ok"] == N and set(seg["statuses"]) >= {"ok", "too small", "empty mask", "no video"}


def test_a_frames_folder_is_a_source_layout_of_the_one_reader(tiny_model, frames_folder, tmp_path):
    """--videos DIR --people 1 (DIR a frames folder: what --frames DIR runs) and --videos DIR/frames --background
    DIR/background --people 1 (the same cameras as a plain recording folder and its empty-room clips)."""
    layout = run_one_person(tiny_model, frames_folder, RecordingOptions(overlays=False))
    plain = run_one_person(tiny_model, frames_folder / "frames", RecordingOptions(
        overlays=False, background=frames_folder / "background"))
    np.testing.assert_array_equal(plain.result.joints, layout.result.joints)
    np.testing.assert_array_equal(plain.contours, layout.contours)
    np.testing.assert_array_equal(plain.status, layout.status)
    assert list(layout.frames) == [f"{i:05d}" for i in range(N)] and list(plain.frames) == list(layout.frames)
    assert (layout.status == "ok").all() and np.isfinite(layout.result.joints).all()


def test_one_person_takes_each_views_largest_blob(tiny_model, tiny_model_file, rig, tools, tmp_path):
    """Two cylinders, one wide and one thin: the view is the wide one's outline; speckle alone is 'too small', an
    empty mask 'empty mask'."""
    big, small = (-0.5, -0.5), (1.2, -0.8)
    both = tools.cylinder_masks(rig, [big])
    both |= tools.cylinder_masks(rig, [small], radius=0.05)
    alone = tools.cylinder_masks(rig, [big])
    assert [cv2.connectedComponents(m)[0] - 1 for m in both] == [2] * len(rig)  # two blobs in every camera
    frames = np.stack([both, both, both], 1)  # (K, 3, H, W)
    frames[0, 1] = 0
    frames[0, 1, 10:14, 10:14] = 255  # cam0, frame 1: speckle only
    frames[1, 2] = 0  # cam1, frame 2: nothing
    for k, cam in enumerate(rig):
        _write(tmp_path / "masks" / cam.name, list(frames[k]))
    fr = run_one_person(tiny_model, tmp_path / "masks", RecordingOptions(masks=True, overlays=False))
    n_pts = tiny_model.layout_.n_points
    assert fr.status[1, 0] == "too small" and fr.area[1, 0] == binarise(frames[0, 1]).sum() > 0
    assert fr.status[2, 1] == "empty mask"
    for k in range(len(rig)):
        ref = extract_contour(binarise(alone[k]), n_pts).points
        for i in range(3):
            if fr.status[i, k] == "ok":
                np.testing.assert_allclose(fr.contours[i, k], ref, atol=1e-9)
    assert (fr.status == "ok").sum() == 3 * len(rig) - 2
    assert not fr.present[1, 0] and not fr.present[2, 1]
    # the command: the same views, written per frame (the joints file of one person and its view statuses)
    out = tmp_path / "j.json"
    res = _invoke("infer", tiny_model_file, "--videos", tmp_path / "masks", "--masks", "--people", "1", "--out", out,
                  "--no-progress")
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert [f["views_present"] for f in doc["frames"]] == [["cam0", "cam1", "cam2", "cam3"], ["cam1", "cam2", "cam3"],
                                                           ["cam0", "cam2", "cam3"]]
    seg = json.loads(out.with_name("j.segmentation.json").read_text())
    assert [f["status"] for f in seg["frames"]] == fr.status.tolist()
    assert "joints inside the person's outline in the views used" in res.output
    res = _invoke("infer", tiny_model_file, "--videos", tmp_path / "masks", "--masks", "--people", "2", "--no-progress")
    assert res.exit_code == 2 and "--people: 2 is not 1" in res.output


def test_the_inside_column_counts_the_joints_opencv_finds_inside_the_used_outlines(tiny_model_file, rig, tools,
                                                                                   tmp_path):
    """``--people 1`` writes, per frame, the share of the placed joints inside the used views' outlines (2 px):
    against ``cv2.pointPolygonTest`` on the outlines silpose traced, with the silhouette fit and without it (a
    thin cylinder, so that the tiny model's unfitted joints stick out of it)."""
    masks = np.stack([tools.cylinder_masks(rig, [p], radius=0.06) for p in tools.walk((-0.4, 0.0), (0.4, 0.2), 3)], 1)
    for k, cam in enumerate(rig):
        _write(tmp_path / "masks" / cam.name, list(masks[k]))
    fr = run_one_person(load_model(tiny_model_file), tmp_path / "masks", RecordingOptions(masks=True, overlays=False))
    shares = {}
    for fit in ("--silhouette-fit", "--no-silhouette-fit"):
        out = tmp_path / f"{fit}.json"
        res = _invoke("infer", tiny_model_file, "--videos", tmp_path / "masks", "--masks", "--people", "1", "--out", out,
                      "--no-progress", fit)
        assert res.exit_code == 0, res.output
        assert "joints inside the person's outline in the views used" in res.output
        shares[fit] = []
        for i, f in enumerate(json.loads(out.read_text())["frames"]):
            world = np.asarray(f["joints"]) + np.asarray(f["root"])
            hits = [cv2.pointPolygonTest(fr.contours[i, k].astype(np.float32).reshape(-1, 1, 2), (float(x), float(y)),
                                         True) >= -2.0 for k in np.flatnonzero(fr.present[i]) for x, y in rig[k].project(world)]
            assert f["inside"] == pytest.approx(np.mean(hits), abs=1e-4)
            shares[fit].append(f["inside"])
    assert max(shares["--no-silhouette-fit"]) < 1.0
    assert min(np.subtract(shares["--silhouette-fit"], shares["--no-silhouette-fit"])) > 0  # the fit moves them in


def test_overlays_png_and_mp4(tiny_model, frames_folder, rig, tmp_path):
    """Drawn at the working resolution (here people 80 px tall: about 70 % of the default rig's size)."""
    png = run_one_person(tiny_model, frames_folder, RecordingOptions(overlays="png", work_person_px=80),
                         overlay_dir=tmp_path / "png")
    files = sorted((tmp_path / "png").glob("*.png"))
    assert [p.stem for p in files] == [f"{i:05d}" for i in range(N)] and png.overlays == [tmp_path / "png"]
    img = cv2.imread(str(files[0]))
    sizes = {cam.name: work_size(cam, rig.workspace.center, 80) for cam in rig}
    w, h = rig.image_size
    assert all(0.6 * w < sw < 0.8 * w for sw, _ in sizes.values())
    tile = (2 * max(sh for _, sh in sizes.values()), 2 * max(sw for sw, _ in sizes.values()), 3)  # 4 cameras, 2 x 2
    assert img.shape == tile and img.std() > 10
    run_one_person(tiny_model, frames_folder, RecordingOptions(overlays="mp4", work_person_px=80),
                   overlay_dir=tmp_path / "mp4")
    for cam in rig.names:
        cap = cv2.VideoCapture(str(tmp_path / "mp4" / f"{cam}.mp4"))
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == N and int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)) == sizes[cam][0]
        cap.release()
    assert not list(tmp_path.glob(".overlays.*"))  # the videos' working folder is gone


def test_several_people_write_png_overlays(tools, tmp_path, tiny_model, rig):
    tools.write_mask_videos(tmp_path / "v", rig, [tools.walk((-1.0, -0.6), (1.0, -0.6), 3),
                                                  tools.walk((1.0, 0.7), (-1.0, 0.7), 3)])
    run_recording(tiny_model, tmp_path / "v", tmp_path / "o", RecordingOptions(masks=True, overlays="png"))
    files = sorted((tmp_path / "o" / "overlays").glob("*.png"))
    w, h = rig.image_size
    assert [p.stem for p in files] == [f"{i:05d}" for i in range(3)]
    assert cv2.imread(str(files[0])).shape == (2 * h, 2 * w, 3)
