"""The benchmark runner: ``python -m benchmarks.run`` end to end on cheap sections, its options, its failures."""

import importlib
import inspect
import json
import math
import subprocess
import sys

import pytest

from benchmarks import run as runner
from benchmarks.subproc import ROOT

CHEAP = [  # small sizes for CI: three subprocesses, well under a minute together
    "--set", "contours.n_samples=4", "--set", "contours.repeats=1",
    "--set", "em.n=400", "--set", "em.d=60", "--set", "em.q=3", "--set", "em.m=2", "--set", "em.iter_runs=3",
    "--set", "inference.frames=300", "--set", "inference.latency_calls=5", "--set", "inference.n_latent=5",
    "--set", "inference.n_components=2",
]


def _bench(tmp_path, *args):
    return subprocess.run([sys.executable, "-m", "benchmarks.run", "--out", str(tmp_path), *args],
                          cwd=ROOT, capture_output=True, text=True)


def test_quick_run_writes_markdown_and_json_with_the_blas_floor(tmp_path):
    proc = _bench(tmp_path, "--quick", "--only", "contours,em,inference", *CHEAP)
    assert proc.returncode == 0, proc.stderr
    report = json.loads((tmp_path / "bench.json").read_text())
    assert report["quick"] is True
    assert {"cpu_count", "numpy", "blas", "python"} <= set(report["machine"])
    sections = {s["section"]: s for s in report["sections"]}
    assert list(sections) == ["contours", "em", "inference"]
    assert all(s["error"] is None and s["rows"] for s in sections.values())
    assert sections["em"]["kwargs"]["n"] == 400 and sections["em"]["kwargs"]["gmm_iters"] == 1  # --set over --quick
    kernels = [r for r in sections["em"]["rows"] if r["quantity"] == "time per EM iteration"]
    kernels += sections["inference"]["rows"]
    # EM's kernel row + the inference rows: batched x 3, one frame, top-3, + consensus, robust, and at M 200
    # one frame plain and robust, batched robust
    assert len(kernels) == 11
    for r in kernels:
        seconds = r.get("seconds", r["value"])
        # both timed, in the same run; their order is not asserted (a tiny CI kernel can come within timing noise
        # of its floor, and tests never assert wall-clock figures)
        assert r["blas_floor_s"] > 0 and seconds > 0
        assert math.isclose(r["over_floor"], seconds / r["blas_floor_s"], rel_tol=1e-12)
    md = (tmp_path / "bench.md").read_text()
    assert proc.stdout == md + "\n"  # the report is also printed
    for name in sections:
        assert f"## {name}" in md
    headers = [ln for ln in md.splitlines() if ln.startswith("| ") and "blas_floor_s" in ln]
    assert len(headers) == 2 and all("over_floor" in h for h in headers)  # the em and inference tables


def test_a_failing_section_is_reported_and_the_run_exits_1(tmp_path):
    proc = _bench(tmp_path, "--only", "contours", "--set", "contours.no_such_argument=1")
    assert proc.returncode == 1
    report = json.loads((tmp_path / "bench.json").read_text())
    assert "no_such_argument" in report["sections"][0]["error"]
    assert "**failed**" in (tmp_path / "bench.md").read_text()


def test_unknown_section_is_a_usage_error(tmp_path):
    proc = _bench(tmp_path, "--only", "em,nope")
    assert proc.returncode == 2 and "nope" in proc.stderr
    assert not (tmp_path / "bench.md").exists()


def test_every_option_has_help_text():
    actions = [a for a in runner.build_parser()._actions if a.option_strings]
    assert {"--quick", "--only", "--set", "--out", "--list", "--update"} <= {s for a in actions for s in a.option_strings}
    assert all(a.help and len(a.help) > 10 for a in actions)


def test_every_section_runs_a_function_that_accepts_its_arguments():
    for name, sec in runner.SECTIONS.items():
        fn = importlib.import_module(sec.module).run
        for kwargs in (sec.full, sec.quick):
            inspect.signature(fn).bind(**kwargs)  # raises TypeError on an unknown argument
        assert sec.what, name
    data_sections = {n for n, s in runner.SECTIONS.items() if "fallback" in s.full}
    assert data_sections == {"memory", "frames", "protocol"}
    assert all(runner.SECTIONS[n].quick["fallback"] == "tiny" and runner.SECTIONS[n].full["fallback"] == "skip"
               for n in data_sections)  # a fresh clone's --quick generates; a full run says what it needs


def test_parse_set_reads_json_values_and_rejects_bad_items():
    assert runner.parse_set(["em.n=5000", "memory.data=data/paper", "memory.repeats=[1,2]"]) == {
        "em": {"n": 5000}, "memory": {"data": "data/paper", "repeats": [1, 2]}}
    for bad in ("em.n", "n=3", "nope.n=3", "em.=3"):
        with pytest.raises(ValueError, match="--set"):
            runner.parse_set([bad])


def test_update_replaces_the_named_sections_and_keeps_the_others_with_their_commit_and_date(tmp_path):
    cheap = ["--set", "contours.n_samples=4", "--set", "contours.repeats=1", "--set", "em.n=400", "--set", "em.d=60",
             "--set", "em.q=3", "--set", "em.m=2", "--set", "em.iter_runs=3"]
    assert _bench(tmp_path, "--quick", "--only", "contours,em", *cheap).returncode == 0
    first = json.loads((tmp_path / "bench.json").read_text())
    em_before = next(s for s in first["sections"] if s["section"] == "em")
    assert em_before["commit"] and em_before["date"]
    # an old report's section without its own commit and date takes the report's machine's
    del em_before["commit"], em_before["date"]
    (tmp_path / "bench.json").write_text(json.dumps(first))
    proc = _bench(tmp_path, "--quick", "--update", "--only", "contours", *cheap)
    assert proc.returncode == 0, proc.stderr
    second = json.loads((tmp_path / "bench.json").read_text())
    assert [s["section"] for s in second["sections"]] == ["contours", "em"]
    contours, em = second["sections"]
    assert em["rows"] == em_before["rows"]  # kept as measured
    assert (em["commit"], em["date"]) == (first["machine"]["commit"], first["machine"]["date"])
    assert contours["date"] >= first["machine"]["date"] and contours["rows"]
    assert f"commit {em['commit']}, {em['date']}" in (tmp_path / "bench.md").read_text()


@pytest.mark.parametrize("case, message", [
    ("no --only", "--update needs --only"),
    ("no report", "no report to update"),
    ("broken report", "field 'sections'"),
    ("other size", "holds --quick figures"),
])
def test_update_refuses_what_it_cannot_merge_with_one_line(tmp_path, case, message):
    if case == "broken report":
        (tmp_path / "bench.json").write_text(json.dumps({"quick": True, "machine": {}, "sections": [{"x": 1}]}))
    if case == "other size":
        (tmp_path / "bench.json").write_text(json.dumps({"quick": True, "machine": {}, "sections": []}))
    args = ["--update"] + ([] if case == "no --only" else ["--only", "contours"])
    args += [] if case == "other size" else ["--quick"]
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = _bench(tmp_path, *args)
    assert proc.returncode == 2 and message in proc.stderr, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
