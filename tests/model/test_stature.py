"""Metric stature from calibrated silhouettes, and the model's 'stature' joint frame."""

import numpy as np
import pytest

from silpose.datagen.testing import synthetic_record
from silpose.model.stature import REFERENCE_STATURE, estimate_stature, stature_per_view
from silpose.shared.camera import Camera, default_rig
from silpose.shared.dataset import DatasetSplit, read_shard, write_shard
from silpose.shared.dataset_schema import build_metadata


@pytest.fixture(scope="module")
def smoke_split(tmp_path_factory):
    """60 stick-figure walkers (silpose.datagen.testing: real masks from projected skeletons, real
    contour extraction) written and read like a generated shard."""
    rig = default_rig()
    config = {"name": "tiny", "seed": 4, "rig": rig.to_dict(), "n_points": 40}
    meta = build_metadata(rig.to_dict()["cameras"], config, 40, generator_version="test")
    path = tmp_path_factory.mktemp("data") / "train-00000-of-00001.parquet"
    write_shard(path, [synthetic_record(config, "train", i) for i in range(60)], meta)
    split = read_shard(path)
    assert isinstance(split, DatasetSplit)
    return split


def _pole_contours(rig, base_xy, heights, n=40):
    """(N, K, n, 2) pixel 'contours' of vertical poles from (x, y, 0) to (x, y, h): the lowest image
    point is the pole's foot on the floor and the highest its top, as for a standing walker."""
    out = []
    for (x, y), h in zip(base_xy, heights):
        z = np.linspace(0.0, h, n)
        pts = np.stack([np.full(n, x), np.full(n, y), z], axis=1)
        out.append(np.stack([cam.project(pts) for cam in rig], axis=0))
    return np.asarray(out)


def test_exact_for_a_vertical_pole_in_every_view():
    rig = default_rig()
    rng = np.random.default_rng(0)
    xy = rng.uniform(-1.4, 1.4, size=(25, 2))
    h = rng.uniform(1.4, 2.1, size=25)
    est = stature_per_view(_pole_contours(rig, xy, h), list(rig))
    np.testing.assert_allclose(est, np.repeat(h[:, None], len(rig), axis=1), atol=1e-9)
    np.testing.assert_allclose(estimate_stature(_pole_contours(rig, xy, h), list(rig)), h, atol=1e-9)


def test_distorted_camera_is_undistorted_first():
    cam0 = default_rig()[0]
    cam = Camera("distorted", cam0.K, cam0.R, cam0.t, cam0.width, cam0.height, dist=np.array([-0.2, 0.05, 0.001, -0.001, 0.0]))
    c = _pole_contours([cam], [(0.3, -0.5)], [1.8])
    assert abs(stature_per_view(c, [cam])[0, 0] - 1.8) < 1e-6
    plain = Camera("plain", cam0.K, cam0.R, cam0.t, cam0.width, cam0.height)
    assert abs(stature_per_view(c, [plain])[0, 0] - 1.8) > 1e-3  # ignoring the distortion would be wrong


def test_absent_views_are_ignored_and_unmeasurable_frames_fall_back():
    rig = default_rig()
    c = _pole_contours(rig, [(0.0, 0.0), (0.5, 0.5)], [1.6, 1.9])
    c[0, 1] += np.array([0.0, -60.0])  # view 1 of frame 0 corrupted: excluded below
    present = np.ones((2, len(rig)), dtype=bool)
    present[0, 1] = False
    np.testing.assert_allclose(estimate_stature(c, list(rig), present), [1.6, 1.9], atol=1e-9)
    c[1] = np.nan  # no view can measure frame 1
    got = estimate_stature(c, list(rig), present, fallback=1.7)
    assert got[1] == 1.7 and abs(got[0] - 1.6) < 1e-9


def test_floor_ray_behind_the_camera_is_nan():
    rig = default_rig()
    cam = rig[0]
    sky = np.array([[[[cam.width / 2, 0.0], [cam.width / 2, 1.0], [cam.width / 2 + 1, 0.5]]]])  # all above the horizon
    assert np.isnan(stature_per_view(sky, [cam])[0, 0])


def test_bad_shapes_raise():
    rig = default_rig()
    with pytest.raises(ValueError, match="shape"):
        stature_per_view(np.zeros((3, 4, 2)), list(rig))
    with pytest.raises(ValueError, match="cameras"):
        stature_per_view(np.zeros((1, 4, 5, 2)), list(rig)[:2])


def test_measures_the_walkers_statures(smoke_split):
    """On extracted contours of posed walkers (stride, bent knees) the estimate tracks the true stature up
    to a constant offset (these stick figures' thick strokes overshoot head and feet by a few cm)."""
    est = estimate_stature(smoke_split.contours, list(smoke_split.rig))
    true = smoke_split.subject["height"]
    assert np.corrcoef(est, true)[0, 1] > 0.95
    assert np.std(est - true) < 0.03 and abs(np.mean(est - true)) < 0.15


def test_stature_frame_model_round_trip_and_scaling(smoke_split, tmp_path, monkeypatch):
    """A 'stature'-frame model is the default with a rig, survives save/load, and its root-relative joints
    (and their std) are the structure-block answer times stature / 1.75 m: doubling the measured stature
    with the same contours doubles them exactly."""
    from silpose.model import posterior
    from silpose.model.persistence import load_model, save_model
    from silpose.model.shape_model import ShapeStructureModel

    s = smoke_split
    m = ShapeStructureModel(2, 8, n_init=1, max_iter=20).fit(s.contours, s.joints, rig=s.rig)
    assert m.layout_.joint_frame == "stature"
    assert ShapeStructureModel(2, 8, n_init=1, max_iter=5).fit(s.contours, s.joints).layout_.joint_frame == "metres"
    with pytest.raises(ValueError, match="rig"):
        ShapeStructureModel(2, 8, joint_frame="stature").fit(s.contours, s.joints)
    loaded = load_model(save_model(tmp_path / "m.npz", m))
    assert loaded.layout_.joint_frame == "stature"
    a = m.infer(s.contours[:5])
    np.testing.assert_array_equal(a.joints, loaded.infer(s.contours[:5]).joints)
    real = posterior.estimate_stature
    monkeypatch.setattr(posterior, "estimate_stature", lambda *args, **kw: 2.0 * real(*args, **kw))
    b = m.infer(s.contours[:5])
    np.testing.assert_allclose(b.joints - b.joints[:, :1], 2.0 * (a.joints - a.joints[:, :1]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(b.joint_std, 2.0 * a.joint_std, rtol=1e-12)


def test_stature_frame_beats_metres_on_walkers_of_other_statures(smoke_split):
    """Train on the shorter half, test on the taller half: modelling joints per stature extrapolates the
    size, raw metres cannot (mean joint error, root-relative)."""
    from silpose.model.shape_model import ShapeStructureModel
    from silpose.shared.skeleton import root_relative

    s = smoke_split
    order = np.argsort(s.subject["height"])
    lo, hi = order[:40], order[40:]
    errs = {}
    for frame in ("metres", "stature"):
        m = ShapeStructureModel(2, 6, joint_frame=frame, n_init=1, max_iter=30)
        m.fit(s.contours[lo], s.joints[lo], rig=s.rig)
        pred = m.infer(s.contours[hi]).joints
        errs[frame] = np.linalg.norm(root_relative(pred) - root_relative(s.joints[hi]), axis=-1).mean()
    assert errs["stature"] < 0.9 * errs["metres"], errs
