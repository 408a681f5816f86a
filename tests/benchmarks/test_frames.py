"""The frames-to-joints benchmark on the tiny generated inputs: stages add up to the total."""

import math

import pytest


@pytest.mark.filterwarnings("ignore:MPPCA. EM did not converge")
def test_frames_rows_are_consistent(tmp_path, tiny_cache):
    from benchmarks.frames import run

    rows = run(n_frames=3, n_background=4, data=str(tmp_path / "absent"), model=str(tmp_path / "absent.npz"),
               fallback="tiny")  # the path a fresh clone's `just bench --quick` takes
    total = rows[-1]
    assert total["n_steps"] == 3 and total["n_cameras"] == 4 and 0.5 < total["mean_iou"] <= 1
    assert total["data"].startswith("tiny generated dataset")
    stages = rows[1:-1]
    assert abs(sum(r["seconds"] for r in stages) - total["seconds"]) < 1e-9
    assert abs(sum(r["share"] for r in stages) - 1.0) < 1e-9
    for r in stages:
        assert math.isclose(r["steps_per_s"], 3 / r["seconds"], rel_tol=1e-12)
