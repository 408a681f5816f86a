"""Identities by appearance (silpose.app.recordings.appearance and the tracker's use of it): the observations
against an independent computation, the per-person model, and a crossing that motion alone gets wrong."""

import numpy as np

from silpose.app.recordings.appearance import (CAP, COLOUR_SD, HIST_BINS, MEMORY, STATURE_SD_M, WIDTH_SD, Look,
                                               PersonLooks, UPPER_SHARE, blob_histograms, colour_histograms, observe)
from silpose.app.recordings.blobs import find_blobs
from silpose.app.recordings.tracking import Tracker, tracker_for_fps


def _height_on_vertical(cam, xy, row: float) -> float:
    """Independent of :func:`stature_at`'s closed form: bisection on ``cam.project`` along the vertical."""
    lo, hi = 0.0, 3.0  # the image row falls as the height rises (upright camera)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if cam.project(np.array([[xy[0], xy[1], mid]]))[0, 1] > row:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def test_stature_and_width_of_a_cylinder_against_its_geometry(rig, tools):
    xy, radius, height = np.array([0.4, -0.3]), 0.2, 1.62
    masks = tools.cylinder_masks(rig, [xy], radius=radius, height=height)
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    rim = np.c_[xy[0] + radius * np.cos(ang), xy[1] + radius * np.sin(ang), np.full(24, height)]
    for k, cam in enumerate(rig):
        blobs = find_blobs((masks[k] > 0).view(np.uint8), 50)
        label = int(np.argmax(blobs.area[1:])) + 1
        look = observe(cam, blobs, label, xy)
        # the blob's top is the top rim's highest image point, seen on the vertical through the floor point
        top_row = float(np.round(cam.project(rim)[:, 1]).min()) - 0.5
        assert abs(look.stature - _height_on_vertical(cam, xy, top_row)) < 0.005
        assert abs(look.stature - height) < 0.06  # the far rim looks a little higher than the axis
        depth = cam.to_camera(np.array([[xy[0], xy[1], 0.9]]))[0, 2]
        assert abs(look.width - 2 * radius) < 0.1 * 2 * radius + 2 * depth / cam.K[0, 0]  # mean width ~ diameter
        assert look.colour is None
    # colour: a frame whose rows above the blob's upper share are red, the rest blue (BGR)
    blobs = find_blobs((masks[1] > 0).view(np.uint8), 50)
    label = int(np.argmax(blobs.area[1:])) + 1
    x, y, w, h = blobs.bbox[label]
    frame = np.zeros(masks[1].shape + (3,), np.uint8)
    frame[:] = (255, 0, 0)
    frame[: y + int(np.ceil(UPPER_SHARE * h))] = (0, 0, 255)
    c = observe(rig[1], blobs, label, xy, frame).colour
    red, blue = (0 * HIST_BINS + 0) * HIST_BINS + HIST_BINS - 1, (HIST_BINS - 1) * HIST_BINS ** 2
    assert c[0, red] == 1.0 and c[1, blue] == 1.0


def test_colour_histograms_against_numpy_histogramdd():
    rng = np.random.default_rng(3)
    px = rng.integers(0, 256, size=(500, 3)).astype(np.uint8)
    upper = rng.uniform(size=500) < 0.4
    h = colour_histograms(px, upper)
    edges = [np.linspace(0, 256, HIST_BINS + 1)] * 3
    for i, sel in enumerate((upper, ~upper)):
        ref = np.histogramdd(px[sel].astype(float), bins=edges)[0].ravel()
        assert np.allclose(h[i], ref / ref.sum())


def test_blob_histograms_are_those_of_the_blobs_own_pixels():
    import cv2

    rng = np.random.default_rng(5)
    checked = 0
    for trial in range(30):  # smooth random blobs (several per mask, some 1 px tall), a random colour frame
        m = (cv2.GaussianBlur(rng.random((60, 70)).astype(np.float32), (0, 0), 2.5) > 0.55).astype(np.uint8)
        big = np.zeros((80, 90), np.uint8)
        big[7:67, 11:81] = m
        big[75, 3:9] = 1  # a one-row blob
        frame = rng.integers(0, 256, big.shape + (3,), dtype=np.uint8)
        blobs = find_blobs(big, 1)
        for label in range(1, len(blobs.area)):
            x, y, w, h = blobs.bbox[label]
            ys, xs = np.nonzero(blobs.labels == label)  # the blob's pixels, in the labelled box's coordinates
            ys, xs = ys + blobs.origin[1], xs + blobs.origin[0]
            want = colour_histograms(frame[ys, xs], ys - y < UPPER_SHARE * h)
            np.testing.assert_array_equal(blob_histograms(frame, blobs, label), want)
            checked += 1
    assert checked > 60


def test_model_means_and_distance_by_hand():
    m = PersonLooks(2)
    rng = np.random.default_rng(0)
    s = 1.7 + 0.03 * rng.standard_normal(MEMORY + 10)
    w = 0.45 * np.exp(0.1 * rng.standard_normal(MEMORY + 10))
    for i in range(MEMORY):
        m.update([Look(s[i], w[i]), None])
    assert np.isclose(m.stature[0], s[:MEMORY].mean()) and np.isclose(m.width[0], w[:MEMORY].mean())
    assert m.count.tolist() == [MEMORY, 0]
    ref = m.stature[0]
    m.update([Look(s[MEMORY], w[MEMORY]), None])  # then an exponential mean with weight 1 / MEMORY
    assert np.isclose(m.stature[0], ref + (s[MEMORY] - ref) / MEMORY)
    # camera 1 has no observation: compared with the model's mean over cameras
    o = Look(m.stature[0] + 0.05, m.width[0] * np.exp(0.3))
    want = (min((0.05 / STATURE_SD_M) ** 2, CAP) + (0.3 / WIDTH_SD) ** 2) / 2
    assert np.isclose(m.distance([None, o]), want) and np.isclose(m.distance([o, None]), want)
    assert np.isnan(m.distance([None, None])) and np.isnan(PersonLooks(2).distance([o, o]))
    # colour: the Bhattacharyya distance of the parts' histograms
    c = PersonLooks(1)
    red, blue = np.zeros((2, HIST_BINS ** 3)), np.zeros((2, HIST_BINS ** 3))
    red[:, 3], blue[:, 48] = 1.0, 1.0
    c.update([Look(1.7, 0.4, red)])
    half = 0.5 * (red + blue)
    b = np.sqrt(1 - np.sqrt(0.5))
    assert np.isclose(c.distance([Look(1.7, 0.4, half)]), 2 * (b / COLOUR_SD) ** 2 / 4)


def _bounce(tracker: Tracker, tall_first: bool = True) -> list[int]:
    """Two people walk towards each other, meet, turn back inside a merged detection and part again; one is
    tall and broad (1.85 m, 0.45 m), the other short and slim (1.60 m, 0.38 m); seen alone in every camera when
    apart. Returns the id on the person who started on the left, per step where both are seen apart."""
    ids = []
    tall, short = [Look(1.85, 0.45)] * 4, [Look(1.60, 0.38)] * 4
    for s in range(70):
        xa = -1 + 0.04 * s if s <= 25 else -0.04 * (s - 25)  # meet at x = 0 at step 25, turn back
        pa, pb = np.array([xa, 0.0]), np.array([-xa, 0.1])
        if abs(2 * xa) < 0.5:  # one detection between them, nobody alone in any view
            det, obs = np.array([(pa + pb) / 2]), [[None] * 4]
        else:
            det, obs = np.array([pa, pb]), ([tall, short] if tall_first else [short, tall])
        out = tracker.update(s, det, None, lambda idx: [obs[i] for i in idx])
        for t, d in out:
            if d >= 0:  # the pipeline's part: every detected person's model learns from their lone views
                t.looks = t.looks or PersonLooks(4)
                t.looks.update(obs[d])
        if len(det) == 2 and s > 10:  # confirmed by then
            ids.append(next(t.person for t, d in out if d == 0))
    return ids


def test_people_who_turn_back_inside_a_merge_keep_their_ids_by_appearance():
    motion = tracker_for_fps(25.0)
    motion.look_weight = 0.0
    ids = _bounce(motion)
    assert ids[0] == 1 and ids[-1] != 1  # motion alone: both carried on across, the ids swapped
    for tall_first in (True, False):
        ids = _bounce(tracker_for_fps(25.0), tall_first)
        assert set(ids) == {1}, ids  # appearance: the ids stay with their people


def test_max_people_reidentifies_the_most_alike_lost_person_wherever_they_come_back():
    """Three people seen, then the tall and the short one vanish; a tall person appears 4.7 m from where the
    tall one was lost (beyond the re-identification gate) and 3.1 m from the short one: with max_people 3 they
    take the tall one's id, without it a new one."""
    def run(max_people: int) -> tuple[int, int]:
        tr = tracker_for_fps(25.0)
        tr.max_people = max_people
        looks = {0: [Look(1.85, 0.45)] * 4, 1: [Look(1.60, 0.38)] * 4, 2: [Look(1.72, 0.40)] * 4}
        for s in range(60):
            people = {0: (-1.2, -1.2), 1: (0.0, 0.0), 2: (1.2, 0.0)} if s < 20 else {2: (1.2, 0.0)}
            if s >= 40:
                people[0] = (1.3, 2.8)
            keys = list(people)
            det = np.array([people[k] for k in keys])
            out = tr.update(s, det, None, lambda idx: [looks[keys[i]] for i in idx])
            for t, d in out:
                if d >= 0:
                    t.looks = t.looks or PersonLooks(4)
                    t.looks.update(looks[keys[d]])
        tall = next(t.person for t, d in out if d >= 0 and keys[d] == 0)
        return tall, tr.n_persons

    assert run(0) == (4, 4)
    assert run(3) == (1, 3)


def test_max_people_reaches_the_tracker_and_is_for_several_people_only(tiny_model_file, two_cylinders, tmp_path,
                                                                       monkeypatch):
    import dataclasses

    from typer.testing import CliRunner

    from silpose.app.recordings import pipeline
    from silpose.shared.cli import build_app

    res = CliRunner().invoke(build_app(), ["infer", str(tiny_model_file), "--videos", str(two_cylinders), "--masks",
                                           "--people", "1", "--max-people", "3", "--out", str(tmp_path / "a.parquet")])
    assert res.exit_code != 0 and "--max-people" in res.output
    made = []
    real_tracker, real_run = pipeline.tracker_for_fps, pipeline.run_recording

    def spy(*args, **kwargs):
        made.append(real_tracker(*args, **kwargs))
        return made[-1]

    def short(model, videos, out, options, **kwargs):  # the real run, three steps of it
        return real_run(model, videos, out, dataclasses.replace(options, max_steps=3), **kwargs)

    monkeypatch.setattr(pipeline, "tracker_for_fps", spy)
    monkeypatch.setattr(pipeline, "run_recording", short)
    res = CliRunner().invoke(build_app(), ["infer", str(tiny_model_file), "--videos", str(two_cylinders), "--masks",
                                           "--max-people", "3", "--overlays", "none", "--out", str(tmp_path / "o"),
                                           "--no-progress"])
    assert res.exit_code == 0, res.output
    assert made[0].max_people == 3 and made[0].look_weight > 0


def test_stature_through_a_lens_against_bisection():
    """With lens distortion (standard or fisheye) the height on the vertical is the bisection's on
    ``cam.project``; the pinhole's closed form alone would be centimetres off there."""
    from silpose.app.recordings.appearance import stature_at
    from silpose.datagen.lab import lab_rig
    from silpose.shared.camera import Camera

    base = lab_rig()[0]
    lenses = [Camera("barrel", base.K, base.R, base.t, base.width, base.height, [-0.3, 0.1, 0.0, 0.0, 0.0]),
              Camera("gopro", base.K, base.R, base.t, base.width, base.height, [0.05, -0.01, 0.0, 0.0], fisheye=True)]
    pinhole = Camera("pinhole", base.K, base.R, base.t, base.width, base.height)
    for cam in lenses:
        for xy, h in (([0.4, -0.3], 1.62), ([-1.0, 0.8], 1.85), ([1.2, 0.2], 1.2)):
            xy = np.array(xy)
            row = float(cam.project(np.array([[xy[0], xy[1], h]]))[0, 1])
            assert abs(stature_at(cam, xy, row) - _height_on_vertical(cam, xy, row)) < 1e-3
        off = [abs(stature_at(pinhole, np.array(xy), float(cam.project(np.array([[*xy, 1.85]]))[0, 1])) - 1.85)
               for xy in ([-1.0, 0.8], [1.2, 0.2])]
        assert max(off) > 0.01  # the lens matters there
