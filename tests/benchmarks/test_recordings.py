"""The recordings benchmark's helpers: the foot-point floor method it compares against, and the
ping-pong long video (the full section renders and trains, so it runs in ``just bench`` only)."""

import cv2
import numpy as np

from silpose.datagen.lab import lab_rig


def _cylinders(rig, where, radius=0.2, height=1.7):
    w, h = rig.image_size
    out = np.zeros((len(rig), h, w), np.uint8)
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    for k, cam in enumerate(rig):
        for x, y in where:
            ring = np.stack([x + radius * np.cos(ang), y + radius * np.sin(ang)], 1)
            px = cam.project(np.concatenate([np.c_[ring, np.zeros(24)], np.c_[ring, np.full(24, height)]]))
            cv2.fillConvexPoly(out[k], np.round(cv2.convexHull(px.astype(np.float32))).astype(np.int32), 1)
    return out


def test_foot_points_find_separate_people_and_lose_merged_ones():
    from benchmarks.recordings import foot_points

    rig = lab_rig()
    apart = np.array([[-1.0, -0.5], [0.9, 0.8]])
    det = foot_points(list(_cylinders(rig, apart)), rig, 150)
    assert len(det) == 2
    err = np.linalg.norm(det[:, None] - apart[None], axis=2).min(axis=1)
    assert (err > 0.1).all() and (err < 0.25).all()  # the lowest pixel is the front of the base, ~radius off
    behind = np.array([[0.0, -0.15], [0.0, 0.15]])  # one behind the other: their blobs merge in every camera
    assert len(foot_points(list(_cylinders(rig, behind)), rig, 150)) == 1


def test_ping_pong_plays_forwards_then_backwards(tmp_path):
    from benchmarks.recordings import _ping_pong

    src = tmp_path / "src"
    src.mkdir()
    w = cv2.VideoWriter(str(src / "cam0.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 25, (64, 48), isColor=False)
    for i in range(4):
        w.write(np.full((48, 64), 40 * i + 20, np.uint8))
    w.release()
    assert _ping_pong(src, tmp_path / "long", 3) == 12
    cap = cv2.VideoCapture(str(tmp_path / "long" / "cam0.mp4"))
    levels = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        levels.append(int(round((img.mean() - 20) / 40)))
    assert levels == [0, 1, 2, 3, 3, 2, 1, 0, 0, 1, 2, 3]


def test_overlay_shares_compare_each_overlay_run_with_its_plain_run():
    from benchmarks.recordings import _overlay_shares

    rows = [{"name": "run", "run": "1x", "steps": 100, "wall_s": 2.0, "cpu_ms_per_step": 10.0},
            {"name": "run", "run": "1x with overlays", "steps": 100, "wall_s": 4.0, "cpu_ms_per_step": 25.0},
            {"name": "run", "run": "colour 4 x 9x9 with overlays", "steps": 10, "wall_s": 1.0, "cpu_ms_per_step": 1.0},
            {"name": "reference", "run": "1x with overlays"}]
    _overlay_shares(rows)
    assert abs(rows[1]["overlay_share_wall"] - 0.5) < 1e-12 and abs(rows[1]["overlay_share_cpu"] - 0.6) < 1e-12
    assert "overlay_share_wall" not in rows[0] and "overlay_share_wall" not in rows[2]  # no plain run to compare


def test_decode_reference_times_every_frame_of_every_camera(tmp_path):
    import cv2

    from benchmarks.recordings import decode_reference

    rng = np.random.default_rng(0)
    for folder, n in (("videos", 3), ("clips", 4)):
        (tmp_path / folder).mkdir()
        for cam in ("cam0", "cam1"):
            w = cv2.VideoWriter(str(tmp_path / folder / f"{cam}.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 25, (64, 48))
            for _ in range(n):
                w.write(rng.integers(0, 256, (48, 64, 3), dtype=np.uint8))
            w.release()
    ref = decode_reference(str(tmp_path / "videos"), str(tmp_path / "clips"), n_background=4)
    assert ref["steps"] == 3
    assert ref["decode_cpu_ms_per_step"] > 0 and ref["mog2_cpu_ms_per_step"] > 0
    assert "segment_cpu_ms_per_step" not in ref  # no model: no working size
