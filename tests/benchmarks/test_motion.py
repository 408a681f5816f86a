"""The motion-capture benchmark on a few samples: rows consistent with their own timings, and the
BVH and walk configs rendered the same number of samples."""

import math

import pytest

from benchmarks.motion import run


@pytest.mark.blender
def test_motion_rows_are_consistent_with_their_timings():
    rows = run(n_samples=3, processes=1, synthetic_frames=12, shard_size=3)
    imp, walk, bvh, *library = rows  # + the bundled motion library's row when the motions preset exists
    assert imp["clips"] == 1 and imp["frames"] == 12 and imp["seconds"] > 0
    assert (walk["name"], bvh["name"]) == ("procedural raster x1", "bvh raster x1")
    assert [r["name"] for r in library] in ([], ["library raster x1"])
    for lib in library:
        assert math.isclose(lib["library_over_procedural"], lib["ms_per_sample"] / walk["ms_per_sample"], rel_tol=1e-12)
    for r in (walk, bvh, *library):
        assert r["samples"] == 3 and math.isclose(r["samples_per_s"], 3 / r["seconds"], rel_tol=1e-12)
        assert math.isclose(r["ms_per_sample"], 1e3 * r["seconds"] / 3, rel_tol=1e-12)
    assert math.isclose(bvh["bvh_over_procedural"], bvh["ms_per_sample"] / walk["ms_per_sample"], rel_tol=1e-12)
