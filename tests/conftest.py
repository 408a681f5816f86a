"""Shared pytest fixtures. Never import bpy here: Blender runs only in spawned workers."""

import pytest


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the xdist_group marks
def pytest_collection_modifyitems(config, items):
    """The tests that use a local Ray instance run last, one after the other, so they share one instance
    (starting Ray costs ~8 s on 2 cores; see ``local_ray``). Their order among themselves is kept. Under
    pytest-xdist (``just test`` runs ``-n 2 --dist loadgroup``) they form one group: one worker runs them all,
    so one Ray instance starts."""
    ray_tests = [it for it in items if "local_ray" in getattr(it, "fixturenames", ())]
    for it in ray_tests:
        it.add_marker(pytest.mark.xdist_group("ray"))
    if ray_tests:
        items[:] = [it for it in items if "local_ray" not in getattr(it, "fixturenames", ())] + ray_tests


@pytest.fixture(scope="session")
def local_ray():
    """A local Ray instance with 2 CPUs, shared by the session's Ray tests (run last, together:
    ``pytest_collection_modifyitems``); skipped when ray is not installed. silpose's Ray executors use a
    running instance when there is one (``ray.is_initialized``)."""
    # Under `uv run pytest`, Ray would start every worker with `uv run` (a re-synced environment per
    # worker; see silpose.datagen.executor.run_ray and silpose.model.streaming.start_ray).
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
        ray = pytest.importorskip("ray")
        from ray._private import ray_constants

        mp.setattr(ray_constants, "RAY_ENABLE_UV_RUN_RUNTIME_ENV", False)  # if ray was imported earlier
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        yield ray
        ray.shutdown()


def _write_v1_shard(path, records: list[dict], metadata: dict) -> None:
    """Write ``records`` in dataset format version 1 (``arrow.fixed_shape_tensor`` columns, raw uint8
    masks), the layout silpose wrote before version 2, with plain pyarrow (not silpose's writer)."""
    import json

    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    meta = dict(metadata, format_version=1)
    cols = {
        "sample_id": pa.array([r["sample_id"] for r in records], pa.int64()),
        "split": pa.array([r["split"] for r in records], pa.string()),
        "seed": pa.array([r["seed"] for r in records], pa.int64()),
        "redraws": pa.array([r["redraws"] for r in records], pa.int32()),
    }
    for name in ("subject", "gait"):
        keys = list(records[0][name])
        cols[name] = pa.StructArray.from_arrays(
            [pa.array(np.float32([r[name][k] for r in records])) for k in keys], names=keys)
    dtypes = {"joints": np.float32, "masks": np.uint8, "contours": np.float32, "contour_centroid": np.float32,
              "contour_scale": np.float32, "contour_length": np.float32, "area": np.int32, "n_blobs": np.int32}
    for name, dt in dtypes.items():
        cols[name] = pa.FixedShapeTensorArray.from_numpy_ndarray(np.stack([np.asarray(r[name], dt) for r in records]))
    tb = np.stack([np.asarray(r["touches_border"], bool) for r in records])
    cols["touches_border"] = pa.FixedSizeListArray.from_arrays(pa.array(tb.ravel()), tb.shape[1])
    table = pa.table(cols).replace_schema_metadata({b"silpose": json.dumps(meta, sort_keys=True).encode()})
    pq.write_table(table, path, compression="zstd", write_page_checksum=True)


@pytest.fixture
def write_v1_shard():
    """``write_v1_shard(path, records, metadata)``: a shard in the previous dataset format (version 1)."""
    return _write_v1_shard


#: a tiny motion-library dataset (``library_dataset``): the motions preset's sources at a few samples
LIBRARY_SMALL = """name = "library-small"
seed = 5
renderer = "raster"
shard_size = 8
n_points = 60
max_redraws = 50
[splits]
train = 24
test = 6
[motion]
source = "library"
procedural_walk = 0.2
mirror = true
"""


@pytest.fixture(scope="session")
def library_dataset(tmp_path_factory):
    """A dataset posed from the bundled motion library (24 train, 6 test samples), made by ``silpose gen``'s own
    pipeline with the raster renderer (one spawned Blender worker)."""
    from silpose.datagen.config import load_config
    from silpose.datagen.pipeline import generate

    root = tmp_path_factory.mktemp("library")
    (root / "small.toml").write_text(LIBRARY_SMALL)
    generate(load_config(root / "small.toml"), root / "ds", workers=1, progress=False)
    return root / "ds"
