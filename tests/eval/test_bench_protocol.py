"""The eval-protocol benchmark times the experiments silpose eval runs, and the bench runner reports them."""

import math

import pytest

from silpose.eval import bench
from silpose.eval.bench_protocol import run_protocol_bench
from silpose.app.training import run_training


@pytest.mark.filterwarnings("ignore:MPPCA. EM did not converge")
def test_protocol_bench_times_each_requested_experiment(stick_dataset, tmp_path):
    model = tmp_path / "m.npz"
    run_training(str(stick_dataset), out=model, n_components=2, n_latent=3, max_iter=5, n_init=1, progress=False)
    rows = run_protocol_bench(str(stick_dataset), str(model), n_test=6, experiments=("E2", "E4"))
    by = {r["experiment"]: r for r in rows}
    assert {"E2", "E4", "all"} <= set(by)
    assert "E1" not in by and "E3" not in by
    assert all(r["seconds"] > 0 and r["n_test"] == 6 for r in rows)
    assert sum(r["seconds"] for r in rows if r["experiment"] in ("E2", "E4")) <= by["all"]["seconds"]
    assert by["all"]["examples_per_s"] == pytest.approx(6 / by["all"]["seconds"])
    md = bench.rows_markdown(rows)
    assert "eval E2" in md and "eval total" in md


def test_protocol_bench_reports_missing_inputs_instead_of_failing(tmp_path):
    rows = run_protocol_bench(str(tmp_path / "nope"), str(tmp_path / "nope.npz"), missing_ok=True)
    assert len(rows) == 1 and "not measured" in rows[0]["note"] and math.isnan(rows[0]["seconds"])
    with pytest.raises(Exception, match="not found"):
        run_protocol_bench(str(tmp_path / "nope"), str(tmp_path / "nope.npz"))


def test_every_bench_section_names_an_importable_function():
    import importlib

    for name, (module, func, full, quick, what) in bench.SECTIONS.items():
        assert callable(getattr(importlib.import_module(module), func)), name
        assert isinstance(full, dict) and isinstance(quick, dict) and what
