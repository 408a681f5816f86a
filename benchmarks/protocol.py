"""Benchmark of the evaluation protocol: seconds per experiment of ``silpose eval``.

Runs :func:`silpose.eval.run.run_evaluation` (everything ``silpose eval`` does, reports written to
a temporary folder, the camera-frames section off) on the first ``n_test`` test examples of a
generated dataset with its trained model, and reports the wall time of each experiment and the
test examples processed per second. The reference ratio is each experiment's share of the total.

    python -m silpose.eval.bench_protocol [--data data/default] [--model models/default.npz] [--n-test 100]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


def run_protocol_bench(data: str = "data/default", model: str = "models/default.npz", n_test: int = 100,
                       experiments=("E1", "E2", "E3", "E4", "E5"), missing_ok: bool = False) -> list[dict]:
    """Rows ``{"name", "experiment", "n_test", "seconds", "examples_per_s", "share"}``; with ``missing_ok``
    a missing dataset or model gives one "not measured" row instead of an error."""
    from .experiments import EvalConfig
    from .run import run_evaluation

    if missing_ok and not (Path(data).is_dir() and Path(model).is_file()):
        return [{"name": "eval protocol", "experiment": "-", "n_test": 0, "seconds": float("nan"),
                 "examples_per_s": float("nan"), "share": float("nan"),
                 "note": f"not measured: {data} or {model} missing (just gen/train)"}]
    config = EvalConfig(n_test=int(n_test), experiments=tuple(experiments))
    with tempfile.TemporaryDirectory(prefix="silpose-bench-eval-") as tmp:
        t0 = time.perf_counter()
        ev, _ = run_evaluation(data, model, tmp, config, frames_dir=False)
        total = time.perf_counter() - t0
    rows = []
    for name, sec in ev.timings.items():
        rows.append({"name": f"eval {name}", "experiment": name, "n_test": int(n_test), "seconds": float(sec),
                     "examples_per_s": n_test / sec if sec > 0 else float("nan"), "share": sec / total})
    rows.append({"name": "eval total", "experiment": "all", "n_test": int(n_test), "seconds": total,
                 "examples_per_s": n_test / total, "share": 1.0})
    return rows


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m silpose.eval.bench_protocol", description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="data/default")
    ap.add_argument("--model", default="models/default.npz")
    ap.add_argument("--n-test", type=int, default=100)
    ap.add_argument("--experiments", default="E1,E2,E3,E4,E5")
    a = ap.parse_args(argv)
    for r in run_protocol_bench(a.data, a.model, a.n_test, tuple(a.experiments.split(","))):
        print(f"{r['name']}: {r['seconds']:.1f} s, {r['examples_per_s']:.1f} test examples/s, {100 * r['share']:.0f} %")


if __name__ == "__main__":
    main()
