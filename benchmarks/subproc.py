"""Run one benchmark function in a fresh Python subprocess and return what it returned.

Every section of ``python -m benchmarks.run`` runs this way (clean peak-memory figures; the driver
never imports bpy, so it can spawn Blender workers), and so does each measurement of the memory
section. The child imports ``module`` from this checkout (its root is put first on ``sys.path``),
calls ``function(**kwargs)`` and prints the JSON of the result after a marker line prefix.
"""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

#: the checkout's root: the folder holding ``benchmarks/``
ROOT = Path(__file__).resolve().parents[1]
MARK = "@@BENCH-RESULT@@"

_CHILD = (
    "import importlib, json, sys; sys.path.insert(0, sys.argv[1]); "
    "result = getattr(importlib.import_module(sys.argv[2]), sys.argv[3])(**json.loads(sys.argv[4])); "
    f"print({MARK!r} + json.dumps(result, default=lambda o: o.item() if hasattr(o, 'item') else str(o)))"
)


@dataclass
class ChildResult:
    """``value``: the function's result (None on failure); ``error``: None, or the exit code and the
    last lines of the child's stderr; ``seconds``: wall time of the subprocess."""

    value: object
    error: str | None
    seconds: float


def call(module: str, function: str, kwargs: dict, env: dict | None = None) -> ChildResult:
    """Run ``module.function(**kwargs)`` in a subprocess (``kwargs`` must be JSON); never raises for
    a failure of the child, which is reported in ``error``."""
    import time

    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, str(ROOT), module, function, json.dumps(kwargs)],
        capture_output=True, text=True, env=env,
    )
    seconds = time.perf_counter() - t0
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(MARK)]
    if proc.returncode != 0 or not lines:
        tail = " | ".join((proc.stderr or proc.stdout).strip().splitlines()[-3:])
        return ChildResult(None, f"exit {proc.returncode}: {tail}", seconds)
    return ChildResult(json.loads(lines[-1][len(MARK):]), None, seconds)
