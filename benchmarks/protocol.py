"""The evaluation protocol: seconds per experiment of ``silpose eval``.

Section ``protocol`` of ``python -m benchmarks.run``. Runs :func:`silpose.eval.run.run_evaluation`
(everything ``silpose eval`` does, reports written to a temporary folder, the camera-frames section
off) on the first ``n_test`` test examples of a generated dataset with its trained model, and reports
the wall time of each experiment and the test examples processed per second. The reference ratio is
each experiment's share of the total. Without the dataset or model, see :mod:`benchmarks.inputs`.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from silpose.eval.experiments import EvalConfig
from silpose.eval.run import run_evaluation

from . import inputs


def run(data: str = "data/default", model: str = "models/default.npz", n_test: int = 100,
        experiments=("E1", "E2", "E3", "E4", "E5"), fallback: str = "skip") -> list[dict]:
    """Rows ``{"name", "experiment", "n_test" (examples evaluated), "seconds", "examples_per_s", "share"}``; the total row adds
    ``data`` (what was measured). Without ``data`` or ``model``: :func:`benchmarks.inputs.resolve`."""
    with tempfile.TemporaryDirectory(prefix="silpose-bench-eval-") as tmp:
        src = inputs.resolve("protocol", data, model, fallback, Path(tmp))
        if src.skip:
            return [inputs.skip_row("eval protocol", src.skip)]
        config = EvalConfig(n_test=int(n_test), experiments=tuple(experiments))
        t0 = time.perf_counter()
        ev, _ = run_evaluation(src.data, src.model, Path(tmp) / "reports", config, frames_dir=False)
        total = time.perf_counter() - t0
    n_test = len(ev.data.test_ids)  # fewer than asked when the test split is smaller
    rows = []
    for name, sec in ev.timings.items():
        rows.append({"name": f"eval {name}", "experiment": name, "n_test": int(n_test), "seconds": float(sec),
                     "examples_per_s": n_test / sec if sec > 0 else float("nan"), "share": sec / total})
    rows.append({"name": "eval total", "experiment": "all", "n_test": int(n_test), "seconds": total,
                 "examples_per_s": n_test / total, "share": 1.0, "data": src.label})
    return rows
