"""The eval-protocol benchmark times the experiments silpose eval runs, on the tiny generated inputs."""

import math

import pytest

from benchmarks.protocol import run


@pytest.mark.filterwarnings("ignore:MPPCA. EM did not converge")
def test_protocol_times_each_requested_experiment(tiny_dir):
    rows = run(str(tiny_dir / "data"), str(tiny_dir / "tiny.npz"), n_test=6, experiments=("E2", "E4"))
    by = {r["experiment"]: r for r in rows}
    assert {"E2", "E4", "all"} <= set(by)
    assert "E1" not in by and "E3" not in by
    assert all(r["seconds"] > 0 and r["n_test"] == 6 for r in rows)
    assert sum(r["seconds"] for r in rows if r["experiment"] in ("E2", "E4")) <= by["all"]["seconds"]
    for r in rows:
        assert math.isclose(r["examples_per_s"], 6 / r["seconds"], rel_tol=1e-12)
        assert math.isclose(r["share"], r["seconds"] / by["all"]["seconds"], rel_tol=1e-12)
    assert by["all"]["data"].endswith("tiny.npz")


def test_protocol_skips_or_generates_when_inputs_are_missing(tmp_path, tiny_cache):
    rows = run(str(tmp_path / "nope"), str(tmp_path / "nope.npz"), fallback="skip")
    assert len(rows) == 1 and rows[0]["skipped"].startswith("skipped: needs") and "nope" in rows[0]["skipped"]
    rows = run(str(tmp_path / "nope"), str(tmp_path / "nope.npz"), n_test=100, experiments=("E2",), fallback="tiny")
    assert rows[-1]["data"].startswith("tiny generated dataset") and rows[-1]["n_test"] == 40  # all the tiny test split
    with pytest.raises(ValueError, match="fallback"):
        run(str(tmp_path / "nope"), str(tmp_path / "nope.npz"), fallback="nope")
