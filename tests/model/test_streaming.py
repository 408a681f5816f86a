"""Out-of-core (streaming) and Ray-distributed MPPCA training against the in-memory fit.

The in-memory fit is the reference (its EM is checked against dense densities and known mixtures in
test_mppca.py). Streaming reads a dataset written as several Parquet shards with the dataset writer
(``silpose.datagen.testing.write_synthetic_dataset``, as in tests/app/test_train_streaming.py). The
``silpose train --streaming`` / ``--executor ray`` commands are tested in tests/app/test_train_streaming.py.
"""

from __future__ import annotations

import subprocess
import sys
import weakref

import numpy as np
import pytest

from silpose.datagen.testing import write_synthetic_dataset
from silpose.model import streaming
from silpose.model.mppca import MPPCA
from silpose.model.shape_model import ShapeStructureModel
from silpose.shared.dataset import load_split

pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")

N_POINTS = 16
SHARD_ROWS = (30, 25, 30, 15)  # uneven shards, 100 rows


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return write_synthetic_dataset(tmp_path_factory.mktemp("data") / "sharded", SHARD_ROWS, N_POINTS)


def _model(**kw):
    args = dict(n_components=3, n_latent=4, structure_weight=10.0, tol=0.0, max_iter=12, n_init=1, random_state=0)
    args.update(kw)
    return ShapeStructureModel(args.pop("n_components"), args.pop("n_latent"), **args)


@pytest.fixture(scope="module")
def start_params(dataset):
    """A start far from the optimum: one EM iteration of a random-start fit on 20 of the 100 rows."""
    split = load_split(dataset, "train")
    m = _model(max_iter=1, random_state=9).fit(split.contours[::5], split.joints[::5])
    mix = m.mixture_
    return {"weights": mix.weights_, "means": mix.means_, "components": mix.components_,
            "noise_variance": mix.noise_variance_}


def _assert_same_fit(a, b, rtol_ll=1e-8, rtol_par=1e-6, moved=True):
    la, lb = np.asarray(a.lower_bounds_), np.asarray(b.lower_bounds_)
    assert la.shape == lb.shape and la.size >= 10
    np.testing.assert_allclose(la, lb, rtol=rtol_ll, atol=0)
    assert np.ptp(la) > 1e-3 or not moved  # EM actually moved from the start
    np.testing.assert_allclose(a.weights_, b.weights_, rtol=rtol_par, atol=1e-12)
    np.testing.assert_allclose(a.noise_variance_, b.noise_variance_, rtol=rtol_par)
    np.testing.assert_allclose(a.means_, b.means_, rtol=rtol_par, atol=1e-9 * np.abs(a.means_).max())
    np.testing.assert_allclose(a.components_, b.components_, rtol=rtol_par, atol=1e-9 * np.abs(a.components_).max())


def test_mppca_stream_over_array_shards_equals_fit():
    rng = np.random.default_rng(0)
    X = np.concatenate([rng.normal(c, 1.0 + c, size=(150, 12)) @ rng.normal(size=(12, 12)) for c in (0.0, 1.0, 3.0)])
    rng.shuffle(X)
    kw = dict(n_components=3, n_latent=3, tol=0.0, max_iter=15, n_init=2, random_state=4)
    ref = MPPCA(**kw).fit(X)
    got = MPPCA(**kw).fit_stream(np.array_split(X, 7))  # 450 rows <= init_rows: the same k-means start
    _assert_same_fit(ref, got)
    assert got.n_features_in_ == 12 and got.n_fit_samples_ == 450


def test_explicit_start_is_validated():
    X = np.random.default_rng(1).normal(size=(40, 5))
    good = {"weights": np.ones(2), "means": np.zeros((2, 5)), "components": np.ones((2, 5, 2)),
            "noise_variance": np.ones(2)}
    with pytest.raises(ValueError, match="n_init must be 1"):
        MPPCA(2, 2, n_init=3, init_params=good).fit(X)
    with pytest.raises(ValueError, match=r"init_params\['means'\] must have shape \(2, 5\)"):
        MPPCA(2, 2, n_init=1, init_params={**good, "means": np.zeros((2, 4))}).fit(X)
    with pytest.raises(ValueError, match="shard 1 contains NaN"):
        MPPCA(2, 2).fit_stream([X[:20], np.full((3, 5), np.nan)])


def test_dataset_stream_equals_in_memory_on_same_start(dataset, start_params):
    split = load_split(dataset, "train")
    ref = _model().fit(split.contours, split.joints, rig=split.rig, init_params=start_params)
    got = _model().fit_stream(dataset, "train", init_params=start_params)
    _assert_same_fit(ref.mixture_, got.mixture_)
    assert got.layout_ == ref.layout_ and got.n_train_ == sum(SHARD_ROWS)
    assert got.rig_.to_dict() == split.rig.to_dict()


def test_dataset_stream_on_a_row_subset_with_default_start(dataset):
    """rows= selects the same samples as indexing in memory; with <= init_rows rows the k-means start is too."""
    split = load_split(dataset, "train")
    rows = np.sort(np.random.default_rng(2).choice(len(split), size=70, replace=False))
    ref = _model(n_init=2).fit(split.contours[rows], split.joints[rows], rig=split.rig)
    got = _model(n_init=2).fit_stream(dataset, "train", rows=rows)
    _assert_same_fit(ref.mixture_, got.mixture_, moved=False)  # the k-means + PPCA start is already near the optimum


def test_streaming_holds_one_shard_of_features(dataset, start_params, monkeypatch):
    """Structural memory bound: each shard's vectors are freed before the next shard is read, the
    initialisation subsample is at most init_rows, and the split is never loaded whole."""
    live: list = []
    calls: list = []
    original = streaming.load_shard_features

    def spy(path, rows, layout, n_rig_views):
        alive = [r for r in live if r() is not None]
        calls.append((len(alive), sum(r().shape[0] for r in alive)))
        X = original(path, rows, layout, n_rig_views)
        live.append(weakref.ref(X))
        calls[-1] += (X.shape[0],)
        return X

    def no_load_split(*a, **k):
        raise AssertionError("streaming must not load the whole split")

    monkeypatch.setattr(streaming, "load_shard_features", spy)
    monkeypatch.setattr("silpose.shared.dataset.load_split", no_load_split)
    _model(max_iter=3).fit_stream(dataset, "train", init_params=start_params, cache=False)
    # passes: moments, first E-step, 3 iterations, the log-likelihood under the dof-corrected noise
    # variances (noise_dof, the default) -> 6 passes x 4 shards
    assert len(calls) == 6 * len(SHARD_ROWS)
    assert all(n_alive == 0 for n_alive, _, _ in calls)
    assert max(rows for _, _, rows in calls) == max(SHARD_ROWS)

    calls.clear()
    live.clear()
    _model(max_iter=2, n_init=1).fit_stream(dataset, "train", init_rows=12, cache=False)
    assert max(rows_alive for _, rows_alive, _ in calls) <= 12  # only the init subsample outlives its read
    assert sum(rows for _, _, rows in calls[len(SHARD_ROWS):2 * len(SHARD_ROWS)]) == 12  # the subsample pass
    assert max(rows for _, _, rows in calls) <= max(SHARD_ROWS)


def test_feature_cache_gives_the_uncached_fit_and_builds_each_shard_once(dataset, monkeypatch):
    """The cached streaming fit equals the uncached one bit for bit (rows subset, k-means start: every pass
    kind); each shard's vectors are built once, later passes read the cache, and its folder is gone after."""
    import tempfile
    from pathlib import Path

    rows = np.sort(np.random.default_rng(5).choice(sum(SHARD_ROWS), size=80, replace=False))
    ref = _model(max_iter=4).fit_stream(dataset, "train", rows=rows, init_rows=30, cache=False)
    built, folders = [], []
    original_build, original_mkdtemp = streaming.load_shard_features, tempfile.mkdtemp

    def count_builds(path, rows, layout, n_rig_views):
        built.append(path)
        return original_build(path, rows, layout, n_rig_views)

    def record_folder(*a, **k):
        folders.append(original_mkdtemp(*a, **k))
        return folders[-1]

    monkeypatch.setattr(streaming, "load_shard_features", count_builds)
    monkeypatch.setattr(tempfile, "mkdtemp", record_folder)
    got = _model(max_iter=4).fit_stream(dataset, "train", rows=rows, init_rows=30)
    a, b = ref.mixture_, got.mixture_
    assert a.lower_bounds_ == b.lower_bounds_ and len(a.lower_bounds_) == 4
    for name in ("weights_", "means_", "components_", "noise_variance_"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert sorted(built) == sorted(set(built)) and len(built) == len(SHARD_ROWS)  # one build per shard
    assert len(folders) == 1 and Path(folders[0]).name.startswith("silpose-features-")
    assert not Path(folders[0]).exists()  # removed after the fit


def test_feature_cache_rejects_a_foreign_file(dataset, tmp_path):
    """A cache file of the wrong shape is an error naming the file, not data."""
    from silpose.model.fitting import model_layout

    src = streaming.DatasetShards.open(dataset, "train")
    layout = model_layout(_model(), src.n_rig_views, src.n_points, src.rig)
    np.save(tmp_path / "shard-00000.npy", np.zeros((3, 2)))
    with pytest.raises(streaming.StreamingError, match=r"shard-00000.npy: cached features .* expected \(rows, "):
        streaming.cached_shard_features(str(tmp_path), 0, src.paths[0], None, layout, src.n_rig_views)


def test_model_imports_without_ray_and_says_so_when_asked_for_it(dataset):
    code = (
        "import sys; sys.modules['ray'] = None\n"
        "import silpose.model, silpose.model.streaming as s\n"
        "from silpose.model.shape_model import ShapeStructureModel\n"
        "m = ShapeStructureModel(2, 3, n_init=1, max_iter=2)\n"
        "try:\n"
        f"    m.fit_stream({str(dataset)!r}, executor='ray')\n"
        "except s.StreamingError as e:\n"
        "    print('ERR', e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "ERR executor 'ray': ray is not installed" in out.stdout


def test_corrupt_shard_is_named(dataset, tmp_path, start_params):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(dataset, bad)
    victim = bad / "train-00002-of-00004.parquet"
    victim.write_bytes(victim.read_bytes()[:-100])
    with pytest.raises(Exception, match="train-00002-of-00004.parquet"):
        _model().fit_stream(bad, "train", init_params=start_params)


# ----------------------------------------------------------------------------- Ray
# (the local_ray fixture is in tests/conftest.py)


@pytest.mark.ray
def test_ray_fit_equals_local_streaming(dataset, start_params, local_ray):
    local = _model().fit_stream(dataset, "train", init_params=start_params)
    via_ray = _model().fit_stream(dataset, "train", executor="ray", init_params=start_params)
    _assert_same_fit(local.mixture_, via_ray.mixture_, rtol_ll=1e-10, rtol_par=1e-8)

