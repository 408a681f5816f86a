"""The recordings workflow's parts: binarising lossy masks, blobs, the floor grid, view assignment, tracking,
placement and the writers (silpose.app.recordings)."""

import cv2
import numpy as np
import pyarrow.parquet as pq

from silpose.app.recordings.blobs import blob_contour, find_blobs
from silpose.app.recordings.floor import FloorGrid
from silpose.app.recordings.chunk_rows import one_row_per_person
from silpose.app.recordings.placement import body_point, place_contours, place_roots, root_height
from silpose.app.recordings.silhouettes import binarise
from silpose.app.recordings.tracking import Tracker
from silpose.app.recordings.views import (VIEW_BORDER, VIEW_CLUTTER, VIEW_EMPTY, VIEW_MERGED, VIEW_NOT_SEEN, VIEW_OK,
                                          VIEW_PARTIAL, assign_views)
from silpose.app.recordings.writers import PersonRows, RecordingWriter
from silpose.datagen.lab import lossy
from silpose.shared.rig_frame import DEFAULT_WORKSPACE
from silpose.shared.skeleton import JOINT_NAMES


def _iou(a, b):
    a, b = a.astype(bool), b.astype(bool)
    return (a & b).sum() / (a | b).sum()


def test_binarise_recovers_lossy_encoded_masks(rig, tools, tmp_path):
    """Our own lossy masks: JPEG q15 then mp4v (what the lab recording writes), and q5 blurred."""
    clean = tools.cylinder_masks(rig, [(-0.8, -0.5), (0.6, 0.8)])[1]
    for quality, blur in ((15, 0), (5, 1.0)):
        src = cv2.GaussianBlur(clean, (0, 0), blur) if blur else clean
        tools.write_video(tmp_path / "m.mp4", np.stack([lossy(src, quality)] * 3))
        cap = cv2.VideoCapture(str(tmp_path / "m.mp4"))
        grey = cv2.cvtColor(cap.read()[1], cv2.COLOR_BGR2GRAY)
        cap.release()
        assert ((grey > 20) & (grey < 235)).sum() > 200  # really smeared
        mask = binarise(grey)
        assert set(np.unique(mask)) <= {0, 1}
        assert _iou(mask, clean) > 0.985
        assert cv2.connectedComponents(mask)[0] == cv2.connectedComponents((clean > 0).view(np.uint8))[0]
        assert cv2.connectedComponents((grey > 40).view(np.uint8))[0] >= cv2.connectedComponents(mask)[0]


def test_find_blobs_labels_the_foreground_box_like_a_full_frame_labelling(rig, tools):
    m = (tools.cylinder_masks(rig, [(-0.8, -0.5), (0.6, 0.8)])[2] > 0).view(np.uint8).copy()
    m[5:9, 300:303] = 1  # speckle
    m[200:260, 0:6] = 1  # a blob on the border
    b = find_blobs(m, min_area=50)
    n, ref, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
    assert len(b.area) == n and sorted(b.area[1:]) == sorted(stats[1:, 4])
    ys, xs = np.nonzero(np.ones_like(m))
    lab = b.label_at(np.stack([xs, ys], 1)).reshape(m.shape)
    assert ((lab > 0) == (ref > 0)).all()  # same foreground, one label per component
    pairs = {(int(a), int(c)) for a, c in zip(lab[m > 0], ref[m > 0])}
    assert len(pairs) == n - 1
    assert b.usable.sum() == 3 and b.touches_border[1:].sum() == 1 and not b.usable[0]
    big = int(np.argmax(np.where(b.usable & ~b.touches_border, b.area, 0)))
    pts = blob_contour(b, big, 50)
    x, y, w, h = b.bbox[big]
    assert pts.shape == (50, 2) and pts[:, 0].min() >= x - 1 and pts[:, 1].max() <= y + h
    assert find_blobs(np.zeros_like(m), 50).empty


def test_floor_grid_finds_people_at_their_positions(rig, tools):
    grid = FloorGrid(list(rig), DEFAULT_WORKSPACE.bounds)
    where = np.array([[-0.9, -0.4], [0.7, 0.9], [0.1, 0.1]])
    masks = [(m > 0).view(np.uint8) for m in tools.cylinder_masks(rig, where)]
    det = grid.locate(masks)
    assert len(det.positions) == 3
    d = np.linalg.norm(det.positions[:, None] - where[None], axis=2)
    assert d.min(axis=1).max() < 0.06 and sorted(d.argmin(axis=1)) == [0, 1, 2]
    # a camera whose mask is all black says nothing; a blob seen by one camera alone is nobody
    masks[3] = None
    speck = np.zeros_like(masks[0])
    speck[100:200, 50:90] = 1
    assert len(grid.locate(masks).positions) == 3
    assert len(grid.locate([speck, None, None, None]).positions) == 0
    # hidden from one camera (cam1 lost the first person): the strict map misses them, the tolerant one not
    full = [(m > 0).view(np.uint8) for m in tools.cylinder_masks(rig, where)]
    full[1] = (tools.cylinder_masks(rig, where[1:])[1] > 0).view(np.uint8)
    assert len(grid.detect(grid.occupancy(full)[0]).positions) == 2
    det = grid.locate(full)
    assert len(det.positions) == 3 and np.linalg.norm(det.positions - where[0], axis=1).min() < 0.08


def test_views_ok_merged_border_not_seen(rig, tools):
    cam = rig[1]
    a, b = np.array([-0.3, -0.8]), np.array([-0.15, 0.9])  # b behind a for cam1: their images overlap
    c = np.array([1.3, 0.0])
    m = (tools.cylinder_masks(rig, [a, b, c])[1] > 0).view(np.uint8)
    labels, status = assign_views(cam, find_blobs(m, 50), np.stack([a, b, c]))
    assert status == [VIEW_MERGED, VIEW_MERGED, VIEW_OK] and labels[0] == labels[1] != labels[2]
    # a blob bigger than a person's cylinder (a prop, someone undetected next to them) is not theirs alone, and
    # not "merged" either (no second tracked person shares it)
    m2 = (tools.cylinder_masks(rig, [c])[1] > 0).view(np.uint8).copy()
    x, y = np.round(cam.project(np.r_[c, 1.0])).astype(int)
    m2[y - 10 : y + 10, x : x + 160] = 1
    assert assign_views(cam, find_blobs(m2, 50), c[None])[1] == [VIEW_CLUTTER]
    m3 = (tools.cylinder_masks(rig, [c])[1] > 0).view(np.uint8)
    assert assign_views(cam, find_blobs(np.zeros_like(m), 50), c[None])[1] == [VIEW_EMPTY]
    assert assign_views(cam, find_blobs(m3, 50), np.array([[-1.2, 1.2]]))[1] == [VIEW_NOT_SEEN]


def test_a_piece_of_a_person_is_partial_not_their_silhouette(rig, tools):
    """Background subtraction splits a person where their clothes match the background, and furniture hides
    their legs: the torso piece (the blob the torso column falls on), an upper body or legs alone is not the
    person's silhouette. The cut rows come from the camera's own projection of heights on the person."""
    cam, c = rig[1], np.array([1.3, 0.0])
    whole = (tools.cylinder_masks(rig, [c])[1] > 0).view(np.uint8)
    assert assign_views(cam, find_blobs(whole, 50), c[None])[1] == [VIEW_OK]

    def row(height):  # image row of the person's axis at this height (m)
        return int(round(cam.project(np.r_[c, height])[1]))

    split = whole.copy()
    split[row(0.75) : row(0.6)] = 0  # a 15 cm gap at the belt: torso blob + legs blob
    labels, status = assign_views(cam, find_blobs(split, 50), c[None])
    assert status == [VIEW_PARTIAL] and find_blobs(split, 50).n_usable == 2
    hidden = whole.copy()
    hidden[row(0.7):] = 0  # legs behind a table
    assert assign_views(cam, find_blobs(hidden, 50), c[None])[1] == [VIEW_PARTIAL]
    short = (tools.cylinder_masks(rig, [c], height=0.9)[1] > 0).view(np.uint8)  # legs alone (hips at 0.9 m)
    assert assign_views(cam, find_blobs(short, 50), c[None])[1] == [VIEW_PARTIAL]
    holed = whole.copy()
    x = int(round(cam.project(np.r_[c, 1.0])[0]))
    holed[row(1.1) : row(1.0), x - 2 : x + 3] = 0  # a hole inside the torso: still one blob spanning the person
    assert assign_views(cam, find_blobs(holed, 50), c[None])[1] == [VIEW_OK]


def test_border_blob_is_not_used(rig):
    cam = rig[0]
    xy = np.array([[0.2, 0.3]])
    px = cam.project(np.array([[0.2, 0.3, 1.1]]))[0]
    m = np.zeros((cam.height, cam.width), np.uint8)
    m[int(px[1]) - 60: cam.height, int(px[0]) - 15: int(px[0]) + 15] = 1  # runs off the bottom edge
    assert assign_views(cam, find_blobs(m, 50), xy)[1] == [VIEW_BORDER]


def test_tracker_keeps_ids_through_a_crossing_and_drops_a_one_frame_ghost():
    tr = Tracker(gate=0.6, max_misses=3, min_hits=3)
    seen = {}
    for step in range(40):
        a = np.array([-1.5 + 0.075 * step, -0.25])
        b = np.array([1.5 - 0.075 * step, 0.25])
        det = [b, a] if step % 2 else [a, b]
        if step == 10:
            det.append(np.array([0.0, 1.4]))  # a ghost, one frame
        if step in (19, 20):
            det = [0.5 * (a + b)]  # the two merge into one detection for two frames
        for t, d in tr.update(step, np.array(det)):
            if t.person and d >= 0:
                seen.setdefault(t.person, []).append(np.array(det)[d])
    assert sorted(seen) == [1, 2] and tr.n_persons == 2
    for person, pos in seen.items():
        x = np.array(pos)[:, 0]
        direction = np.sign(np.diff(x))
        assert (direction == direction[0]).mean() > 0.95  # each id keeps walking one way: no swap
    tr2 = Tracker(max_misses=2, min_hits=2)
    for step in range(3):
        tr2.update(step, np.array([[0.0, 0.0]]))
    for step in range(3, 7):
        tr2.update(step, np.zeros((0, 2)))
    out = tr2.update(7, np.array([[0.0, 0.0]]))
    assert tr2.n_persons == 1 and out[0][0].person == 0  # reappearing after the track ended: a new track


def test_a_new_track_never_takes_the_id_of_a_person_seen_elsewhere_after_it_began():
    """Pose2Sim's two-person demo wrote one id at two places for 10 frames: a track that began 1.3 m away while
    person 1 was still detected took their id when they were lost, and its held-back rows went out under it. An
    id is one person at a time: a person who vanished before the new track began is still re-identified, and so
    is one whose detection split in two (the new track began within the association gate)."""
    def run(b_starts: int, b_at=(1.2, 0.3)) -> tuple[dict, Tracker]:
        tr = Tracker(gate=0.6, max_misses=10, min_hits=3, reid_gate=3.0, recent=1)
        where = {}
        for step in range(14):
            det = [np.array([0.0, 0.0])] if step < 6 else []  # person A, gone after step 5
            if step >= b_starts:
                det.append(np.array(b_at))  # B, 1.2 m away (within the re-identification gate)
            for t, d in tr.update(step, np.array(det).reshape(-1, 2)):
                if d >= 0:
                    where.setdefault(t.key, []).append((step, t))
        return where, tr

    where, tr = run(b_starts=4)  # B began while A was still seen: two people
    ids = {key: rows[-1][1].person for key, rows in where.items()}
    steps = {key: {s for s, _ in rows} for key, rows in where.items()}
    assert tr.n_persons == 2 and len(set(ids.values())) == 2
    for k1 in ids:  # no id at two places in one step
        for k2 in ids:
            if k1 < k2 and ids[k1] == ids[k2]:
                assert not steps[k1] & steps[k2]
    where, tr = run(b_starts=8)  # B appeared after A vanished: the same person, re-identified
    assert tr.n_persons == 1 and {rows[-1][1].person for rows in where.values()} == {1}
    where, tr = run(b_starts=4, b_at=(0.3, 0.1))  # A's detection split, then only the second part stayed
    assert tr.n_persons == 1 and {t.person for rows in where.values() for _, t in rows} - {0} == {1}


def test_one_row_per_person_keeps_the_older_tracks_row():
    steps = np.array([5, 5, 5, 6, 6, 7])
    person = np.array([1, 1, 2, 1, 0, 1])
    began = np.array([9, 2, 4, 9, 1, 9])  # at step 5 id 1 is held by a track from step 9 and one from step 2
    keep = one_row_per_person(steps, person, began)
    assert keep.tolist() == [False, True, True, True, False, True]
    rng = np.random.default_rng(0)  # against a dictionary, on random rows
    steps, person, began = rng.integers(0, 6, 200), rng.integers(0, 4, 200), rng.integers(0, 50, 200)
    best = {}
    for i in range(200):
        if person[i] > 0:
            k = (steps[i], person[i])
            if k not in best or (began[i], i) < (began[best[k]], best[k]):
                best[k] = i
    assert set(np.flatnonzero(one_row_per_person(steps, person, began))) == set(best.values())


def _body(rng):
    """(19, 3) root-relative joints of an upright, slightly random body."""
    j = np.zeros((19, 3))
    j[:, 2] = np.linspace(0.8, -0.95, 19)
    j[:, :2] = rng.normal(0, 0.1, (19, 2))
    j[0] = 0
    return j


def test_place_roots_recovers_the_root_from_consistent_views(rig):
    rng = np.random.default_rng(0)
    n = 6
    joints = np.stack([_body(rng) for _ in range(n)])
    truth = np.c_[rng.uniform(-1, 1, (n, 2)), root_height(joints)]
    cams = list(rig)
    cen = np.stack([cam.project(truth + body_point(joints)) for cam in cams], axis=1)  # (n, K, 2)
    one_view = np.eye(4, dtype=bool)[[0, 1, 2, 3, 1, 2]]
    for present in (np.ones((n, 4), bool), one_view):  # a prior at the truth: the views agree, nothing moves
        r = place_roots(joints, cen, present, cams, truth[:, :2])
        assert np.allclose(r, truth, atol=1e-6)
    prior = truth[:, :2] + rng.normal(0, 0.15, (n, 2))
    prior_err = np.linalg.norm(prior - truth[:, :2], axis=1)
    for present, gain in ((np.ones((n, 4), bool), 4), (one_view, 1.5)):  # a prior ~15 cm off: the views pull it back
        r = place_roots(joints, cen, present, cams, prior)
        assert np.allclose(r[:, 2], truth[:, 2])
        err = np.linalg.norm(r[:, :2] - truth[:, :2], axis=1)
        assert err.mean() < prior_err.mean() / gain


def test_place_roots_lifts_a_person_on_a_platform_only_when_the_views_agree(rig):
    """Centroids of people standing 0.25 m up (a treadmill) in 2-4 views: the free-height fit finds the height
    (brute-force reference: the true root); in one view, or 5 cm up (within the fit's spread), the feet stay on
    the floor."""
    rng = np.random.default_rng(3)
    n = 8
    joints = np.stack([_body(rng) for _ in range(n)])
    floor = np.c_[rng.uniform(-1, 1, (n, 2)), root_height(joints)]
    cams = list(rig)
    views = np.ones((n, 4), bool)
    views[4:6, 2:] = False  # two views
    views[6:, 1:] = False   # one view
    for lift, lifted in ((0.25, [True] * 6 + [False] * 2), (0.05, [False] * n)):
        truth = floor + [0, 0, lift]
        cen = np.stack([cam.project(truth + body_point(joints)) for cam in cams], axis=1)
        r = place_roots(joints, cen, views, cams, truth[:, :2])  # a prior at the truth: the views agree
        up = r[:, 2] > floor[:, 2] + 1e-6
        assert up.tolist() == lifted, (lift, r[:, 2] - floor[:, 2])
        assert np.allclose(r[up], truth[up], atol=1e-3)
        r = place_roots(joints, cen, views, cams, truth[:, :2] + rng.normal(0, 0.03, (n, 2)))  # a prior 3 cm off
        assert (r[:, 2] > floor[:, 2] + 1e-6).tolist() == lifted
        assert np.all(np.abs(r[up, 2] - truth[up, 2]) < 0.03)


def test_place_contours_maps_missing_views_with_the_observed_metric_scale(rig):
    from silpose.model.shape_model import InferenceResult

    rng = np.random.default_rng(1)
    joints = _body(rng)[None]
    root = np.array([[0.3, 0.2, root_height(joints)[0]]])
    X = root + body_point(joints)
    cams = list(rig)
    depth = np.array([cam.to_camera(X)[0, 2] for cam in cams])
    rho = 0.5
    scale = rho * cams[0].K[0, 0] / depth
    norm = rng.normal(0, 1, (1, 4, 30, 2))
    cen = np.stack([cam.project(X)[0] for cam in cams])
    present = np.array([[True, True, False, True]])
    px = norm * scale[None, :, None, None] + cen[None, :, None, :]
    px[~present] = np.nan
    res = InferenceResult(joints=joints, joints_best=joints, joint_std=joints, contours_norm=norm, contours_px=px,
                          centroid=np.where(present[..., None], cen[None], np.nan), scale=np.where(present, scale, np.nan),
                          views_present=present, responsibilities=np.ones((1, 1)), log_marginal=np.zeros(1),
                          views=(0, 1, 2, 3))
    out = place_contours(res, root, cams)
    expect = norm[0, 2] * scale[2] + cen[2]
    assert np.allclose(out[0, 2], expect) and np.allclose(out[0, [0, 1, 3]], px[0, [0, 1, 3]])


def test_writer_streams_parquet_and_csv_and_abort_leaves_nothing(tmp_path, monkeypatch):
    from silpose.app.recordings import writers

    monkeypatch.setattr(writers, "ROW_GROUP", 3)
    R, K, V, n = 3, 4, 4, 5
    rows = PersonRows(frame=np.arange(R), person=np.array([1, 2, 1]), status=np.array(["ok", "no usable view", "ok"], object),
                      floor=np.zeros((R, 2)), view_status=np.full((R, K), "ok", object), views_used=np.ones((R, K), bool),
                      view_cut=np.zeros((R, K)),
                      log_marginal=np.array([1.0, np.nan, 2.0]), plausibility=np.array([40.0, np.nan, 0.5]),
                      hypothesis=np.array([1, 0, 2]), hypothesis_probability=np.array([0.9, np.nan, 0.3]),
                      joints=np.arange(R * 57.0).reshape(R, 19, 3),
                      joints_calibration=np.ones((R, 19, 3)), joint_std=np.zeros((R, 19, 3)), root=np.ones((R, 3)),
                      root_calibration=np.ones((R, 3)), contours=np.zeros((R, V, n, 2)),
                      inside=np.array([0.75, np.nan, 1.0]))
    cams = [f"cam{k}" for k in range(K)]
    w = RecordingWriter(tmp_path / "j.parquet", tmp_path / "j.csv", cams, cams, n, 25.0, {"a": 1}, contours=True)
    w.write(rows)
    w.write(rows.take([0]))
    assert not (tmp_path / "j.parquet").exists()  # only under a temporary name until closed
    w.close()
    assert pq.ParquetFile(tmp_path / "j.parquet").num_row_groups == 2  # 3 rows, then the last one at close
    t = pq.read_table(tmp_path / "j.parquet")
    assert t.num_rows == 4 and t.column("time").to_pylist()[:3] == [0.0, 0.04, 0.08]
    j = np.array(t.column("joints").to_pylist(), float)
    assert j.shape == (4, 19, 3) and np.array_equal(j[:3], rows.joints)
    assert np.array(t.column("contours_px").to_pylist()).shape == (4, V, n, 2)
    assert t.column("hypothesis").to_pylist() == [1, 0, 2, 1]
    np.testing.assert_allclose(t.column("plausibility").to_numpy()[[0, 2, 3]], [40.0, 0.5, 40.0])
    import csv

    with open(tmp_path / "j.csv", newline="") as f:
        lines = list(csv.reader(f))
    header = lines[0]
    assert len(lines) == 5 and header[:4] == ["frame", "time", "person", "status"]
    assert lines[1][header.index("views")] == "cam0,cam1,cam2,cam3"
    assert float(lines[1][header.index(f"{JOINT_NAMES[1]}_x")]) == rows.joints[0, 1, 0]
    assert all(len(r) == len(header) for r in lines)
    w2 = RecordingWriter(tmp_path / "k.parquet", tmp_path / "k.csv", cams, cams, n, 25.0, {})
    assert "contours_px" not in w2.schema.names
    w2.write(rows)
    w2.abort()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["j.csv", "j.parquet"]


def test_grounded_tells_a_person_from_a_point_behind_them(rig, tools):
    from silpose.app.recordings.views import grounded

    person = np.array([0.3, -0.6])
    cam = rig[1]
    ray = person - cam.center[:2]
    ghost = person + 1.0 * ray / np.linalg.norm(ray)  # 1 m farther along cam1's line of sight
    m = (tools.cylinder_masks(rig, [person])[1] > 0).view(np.uint8)
    b = find_blobs(m, 50)
    torso = np.round(cam.project(np.r_[ghost, 1.1])).astype(int)
    assert b.label_at(torso) > 0  # its torso falls on the person's blob
    assert grounded(cam, b, np.stack([person, ghost])).tolist() == [True, False]
    assert grounded(cam, find_blobs(np.zeros_like(m), 50), person[None]).tolist() == [False]



def _whole_map_peaks(grid, occupancy, min_score):
    """The peaks FloorGrid.detect looks for, computed on the whole map (the reference of its search box)."""
    smooth = cv2.GaussianBlur(occupancy.astype(np.float32), (0, 0), 2.0)
    peak = (smooth >= cv2.dilate(smooth, np.ones((5, 5), np.uint8))) & (smooth >= min_score)
    rows, cols = np.nonzero(peak)
    return smooth, {(float(grid.xs[c]), float(grid.ys[r])) for r, c in zip(rows, cols)}


def test_floor_grid_searches_only_around_occupied_cells_and_finds_the_whole_maps_peaks(rig):
    """FloorGrid.detect smooths and searches the box around the non-zero cells: the same peaks (each detection
    starts at one, and its score is the smoothed value there) as on the whole map, for blobs at the map's edges,
    scattered cells and an empty map."""
    grid = FloorGrid(list(rig), DEFAULT_WORKSPACE.bounds)
    rng = np.random.default_rng(3)
    ny, nx = grid.X.shape
    for trial in range(12):
        occ = np.zeros((ny, nx), np.float32)
        for _ in range(trial % 4):  # people-sized patches anywhere, corners included
            i, j = rng.integers(0, ny), rng.integers(0, nx)
            occ[max(0, i - 4): i + 5, max(0, j - 4): j + 5] = rng.uniform(0.6, 1.0)
        if trial >= 8:
            occ[rng.random(occ.shape) < 0.01] = 1.0
        for min_score in (0.7, 0.2):
            smooth, peaks = _whole_map_peaks(grid, occ, min_score)
            det = grid.detect(occ, min_score, separation=0.0 if trial % 2 else 0.5)
            assert len(det.positions) <= len(peaks)
            for s in det.scores:
                assert np.any(np.isclose(smooth, s, rtol=0, atol=0)), s
            if trial % 2:  # no separation: one detection per peak
                assert len(det.positions) == len(peaks)
    assert len(grid.detect(np.zeros((ny, nx), np.float32)).positions) == 0

def test_tracker_starts_and_confirms_tracks_only_from_allowed_detections():
    tr = Tracker(min_hits=2)
    p = np.array([[0.0, 0.0]])
    assert tr.update(0, p, np.array([False])) == []  # may not start a track
    tr.update(1, p, np.array([True]))
    tr.update(2, p, np.array([False]))  # continues the tentative track, does not count as a hit
    assert tr.n_persons == 0
    tr.update(3, p, np.array([True]))
    assert tr.n_persons == 1


def test_floor_grid_takes_pixels_a_lens_model_sends_to_infinity_without_warning(rig, tools, monkeypatch):
    """Far beyond a distorted camera's lens model the projection overflows to +-inf or NaN (Pose2Sim's demo rig
    did): the grid casts them to indices without a RuntimeWarning, those cells are unseen, and people are found."""
    import warnings

    from silpose.app.recordings import floor

    true_projection = floor.project_fast

    def overflowing(cam, pts):  # the first camera's lens model overflows beyond 1.5 m; the others see there
        px = true_projection(cam, pts)
        if cam.name == rig[0].name:
            far = np.linalg.norm(pts[:, :2], axis=1) > 1.5
            px[far & (pts[:, 2] > 1.0)] = np.inf
            px[far & (pts[:, 2] <= 1.0)] = -np.inf
        return px

    monkeypatch.setattr(floor, "project_fast", overflowing)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        grid = FloorGrid(list(rig), DEFAULT_WORKSPACE.bounds, margin=3.0)
    far = np.hypot(grid.X.ravel()[grid.active], grid.Y.ravel()[grid.active]) > 1.5 + grid.cell
    assert far.any() and not grid.sees[0][far].any()  # the other cameras see there, the first does not
    assert all(0 <= int(i.min()) and int(i.max()) < c.width * c.height for i, c in zip(grid.index, rig))
    where = np.array([[0.7, 0.9]])
    det = grid.locate([(m > 0).view(np.uint8) for m in tools.cylinder_masks(rig, where)])
    assert len(det.positions) == 1 and np.linalg.norm(det.positions[0] - where[0]) < 0.06
