"""Working resolution (:mod:`silpose.app.recordings.resolution`): the scaled camera agrees with OpenCV's resize,
and a run at a reduced working size finds the same people, views and joints as at the cameras' own size."""

from __future__ import annotations

import cv2
import numpy as np
import pyarrow.parquet as pq

from silpose.app.recordings.pipeline import RecordingOptions, run_recording
from silpose.app.recordings.resolution import person_height_px, to_rig_px, to_work_px, work_camera, work_size


def test_work_camera_projects_where_cv2_resize_puts_the_pixel(rig):
    cam = rig[0]
    work = work_camera(cam, (cam.width // 4, cam.height // 4))
    img = np.zeros((cam.height, cam.width), np.float32)
    X = np.array([0.3, -0.2, 1.1])
    u, v = cam.project(X[None])[0]
    img[int(round(v)) - 6: int(round(v)) + 6, int(round(u)) - 6: int(round(u)) + 6] = 1.0  # a 12 px square
    small = cv2.resize(img, (work.width, work.height), interpolation=cv2.INTER_AREA)
    ys, xs = np.nonzero(small)
    centre = np.array([np.average(xs, weights=small[ys, xs]), np.average(ys, weights=small[ys, xs])])
    square_centre = np.array([round(u) - 0.5, round(v) - 0.5])  # the square's centre in cam's pixels
    assert np.allclose(to_work_px(square_centre, cam, work), centre, atol=0.05)
    assert np.allclose(work.project(X[None])[0], to_work_px(np.array([u, v]), cam, work), atol=1e-9)
    assert np.allclose(to_rig_px(to_work_px(np.array([u, v]), cam, work), cam, work), [u, v])


def test_work_size_scales_a_tall_person_to_the_working_height_and_never_enlarges(rig):
    cam = rig[1]
    h = person_height_px(cam, (0.0, 0.0))
    assert work_size(cam, (0.0, 0.0), person_px=2 * h) == (cam.width, cam.height)
    w, hh = work_size(cam, (0.0, 0.0), person_px=h / 2)
    assert abs(w - cam.width / 2) <= 1 and abs(hh - cam.height / 2) <= 1
    assert abs(person_height_px(work_camera(cam, (w, hh)), (0.0, 0.0)) - h / 2) < 1.0


def test_a_run_at_a_third_of_the_size_finds_the_same_people_and_joints(rig, tiny_model, tools, tmp_path):
    videos = tmp_path / "v"
    tools.write_mask_videos(videos, rig, [tools.walk((-1.0, -0.6), (1.0, -0.6), 8), tools.walk((1.0, 0.7), (-1.0, 0.7), 8)])
    full = run_recording(tiny_model, videos, tmp_path / "full", RecordingOptions(masks=True, overlays=False,
                                                                                work_person_px=0))
    h = min(person_height_px(c, (0.0, 0.0)) for c in rig)
    small = run_recording(tiny_model, videos, tmp_path / "small", RecordingOptions(masks=True, overlays=True,
                                                                                  work_person_px=int(h / 3)))
    assert full.n_persons == small.n_persons == 2 and full.views_hist == small.views_hist
    a, b = (pq.read_table(tmp_path / d / "joints.parquet").to_pandas() for d in ("full", "small"))
    ja, jb = (np.stack(t["joints"].map(lambda j: np.stack(j)).to_list()) for t in (a, b))
    # people 50 px tall, contour points off by up to a working pixel (3 camera px): joints within 2 cm of the
    # full-size run's on average (measured 1.4 cm), 6 cm at worst (5.2 cm)
    err = np.linalg.norm(ja - jb, axis=-1)
    assert np.nanmean(err) < 0.02 and np.nanmax(err) < 0.06
    overlay = cv2.VideoCapture(str(tmp_path / "small" / "overlays" / "cam0.mp4"))
    assert overlay.get(cv2.CAP_PROP_FRAME_WIDTH) < rig[0].width / 2  # overlays drawn at the working size


def test_shrink_matches_cv2_inter_area_on_smooth_images_and_keeps_pixel_centres():
    from silpose.app.recordings.resolution import shrink

    rng = np.random.default_rng(0)
    # 1288x972 -> 461x348 (two stages: x2 block average, then bilinear by 1.40), an odd size (one stage), x3
    for (w, h), size in (((1288, 972), (461, 348)), ((1287, 971), (461, 348)), ((966, 729), (322, 243))):
        smooth = cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 6) * 4000 - 1900
        img = np.clip(smooth, 0, 255).astype(np.uint8)
        ref = cv2.resize(img, size, interpolation=cv2.INTER_AREA)  # the reference: OpenCV's area average
        out = shrink(img, size)
        assert out.shape == ref.shape and out.dtype == np.uint8
        assert np.abs(out.astype(int) - ref).mean() < 1.0 and np.abs(out.astype(int) - ref).max() <= 8
        # a bright square's centre lands where work_camera says (x' = (x + 0.5) s - 0.5)
        sq = np.zeros((h, w), np.float32)
        sq[400:440, 500:540] = 1.0
        small = shrink(sq, size)
        ys, xs = np.nonzero(small)
        centre = np.array([np.average(xs, weights=small[ys, xs]), np.average(ys, weights=small[ys, xs])])
        expect = (np.array([519.5, 419.5]) + 0.5) * (size[0] / w, size[1] / h) - 0.5
        assert np.allclose(centre, expect, atol=0.05)
    assert shrink(img, (img.shape[1], img.shape[0])) is img
