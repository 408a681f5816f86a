"""``silpose bench``: run every package's benchmark and write one report.

Each section runs in its own Python subprocess (clean peak-memory figures; the driver never
imports bpy) and returns rows of figures. Every figure sits next to a reference measured in the
same run (the full-covariance GMM for EM, dense conditioning for inference, Blender's own render
for the raster renderer, OpenCV's MOG2 for segmentation, ``cv2.findContours`` for contours), so
ratios stay meaningful on a shared, noisy machine. Output: ``reports/bench/bench.md`` and
``bench.json`` (each row with its unit, plus the machine and library versions).
"""

from __future__ import annotations

import importlib.util
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

# name -> (module, function, full kwargs, quick kwargs, what it measures)
SECTIONS: dict[str, tuple[str, str, dict, dict, str]] = {
    "generation": (
        "silpose.datagen.bench",
        "run_render_bench",
        {"n_samples": 200, "memory_samples": 1000},
        {"n_samples": 16, "memory_samples": 0, "shard_size": 8},
        "samples/s per process and on all cores for the raster and Blender renderers; worker RSS growth",
    ),
    "pipeline": (
        "silpose.datagen.bench_pipeline",
        "run_pipeline_bench",
        {"n_samples": 1000, "workers": 2},
        {"n_samples": 40, "workers": 2, "executors": ["local"]},
        "the whole `silpose gen` pipeline (shards, manifest) on the local spawn pool vs Ray (local instance, "
        "startup included); arrays compared",
    ),
    "em": (
        "silpose.model.bench_em",
        "run_em_bench",
        {},
        {"n": 2000, "d": 417, "q": 10, "m": 3, "gmm_iters": 1, "n_init": 1, "iter_runs": 3},
        "MPPCA EM per iteration and full fit vs sklearn GaussianMixture(full); held-out log-lik; peak memory",
    ),
    "inference": (
        "silpose.model.bench_infer",
        "run",
        {},
        {"frames": 2000, "repeats": 1, "latency_calls": 50},
        "batched frames/s (4 views) and single-frame latency vs dense conditioning",
    ),
    "memory": (
        "silpose.model.bench_memory",
        "run_memory_bench",
        {"data": "data/paper", "repeats": [1, 2, 4], "modes": ["memory", "stream"], "max_iter": 1,
         "missing_ok": True},
        {"data": "data/default", "repeats": [1, 2], "modes": ["memory", "stream"], "n_components": 2,
         "n_latent": 10, "max_iter": 1, "missing_ok": True},
        "peak RSS of the in-memory vs streaming (out-of-core) MPPCA fit; dataset repeated 1x/2x/4x at fixed shard size",
    ),
    "segmentation": (
        "silpose.segment.bench",
        "run_segment_bench",
        {"n_frames": 200},
        {"n_frames": 40, "n_background": 20},
        "background subtraction frames/s per core at 320x240 vs OpenCV MOG2",
    ),
    "frames": (
        "silpose.eval.bench_frames",
        "run_frames_bench",
        {"n_frames": 200, "n_background": 50},
        {"n_frames": 16, "n_background": 10},
        "frames -> joints (4 cameras) time steps/s: PNG reading, segmentation, contours, inference "
        "(composited frames from data/default, models/default.npz)",
    ),
    "protocol": (
        "silpose.eval.bench_protocol",
        "run_protocol_bench",
        {"n_test": 500, "missing_ok": True},
        {"n_test": 40, "experiments": ["E2", "E4"], "missing_ok": True},
        "the evaluation protocol (silpose eval): seconds per experiment on data/default with models/default.npz",
    ),
}

_SNIPPET = (
    "import json, sys, importlib; m = importlib.import_module(sys.argv[1]); "
    "rows = getattr(m, sys.argv[2])(**json.loads(sys.argv[3])); "
    "print('@@ROWS@@' + json.dumps(rows, default=lambda o: o.item() if hasattr(o, 'item') else str(o)))"
)


def run_section(name: str, quick: bool) -> dict:
    """Run one section in a subprocess; returns {name, rows, seconds, error}."""
    module, func, full, small, what = SECTIONS[name]
    out = {"section": name, "what": what, "module": module, "rows": [], "error": None}
    if importlib.util.find_spec(module) is None:
        out["error"] = f"{module} is not installed"
        return out
    kwargs = small if quick else full
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", _SNIPPET, module, func, json.dumps(kwargs)],
        capture_output=True,
        text=True,
    )
    out["seconds"] = time.perf_counter() - t0
    out["kwargs"] = kwargs
    marker = [line for line in proc.stdout.splitlines() if line.startswith("@@ROWS@@")]
    if proc.returncode != 0 or not marker:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
        out["error"] = f"exit {proc.returncode}: " + " | ".join(tail)
        return out
    out["rows"] = json.loads(marker[-1][len("@@ROWS@@") :])
    return out


def machine_info() -> dict:
    import numpy

    info = {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "numpy": numpy.__version__,
        "load_average": list(os.getloadavg()),
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
    }
    try:
        with open("/proc/cpuinfo") as fh:
            info["cpu"] = next((ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), "?")
    except OSError:
        pass
    for pkg in ("scikit-learn", "pyarrow", "opencv-python-headless", "bpy"):
        try:
            from importlib.metadata import version

            info[pkg] = version(pkg)
        except Exception:
            pass
    return info


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list):
        return "[" + ", ".join(_fmt(v) for v in value[:6]) + (", …" if len(value) > 6 else "") + "]"
    return str(value)


def rows_markdown(rows: list[dict]) -> str:
    """Markdown table over the union of the rows' keys (first-seen order)."""
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys and k != "rss_curve_mb"]
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(_fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


def report_markdown(results: list[dict], info: dict, quick: bool) -> str:
    parts = [
        "# silpose benchmarks" + (" (quick)" if quick else ""),
        "",
        "Machine: " + ", ".join(f"{k} {v}" for k, v in info.items()),
        "",
        "Each figure has its reference measured in the same run; the machine is shared, so absolute "
        "timings are noisy and the ratios are the figures to compare.",
    ]
    for res in results:
        parts += ["", f"## {res['section']}", "", f"{res['what']} (`{res['module']}`, "
                  f"{res.get('seconds', 0):.0f} s, arguments {json.dumps(res.get('kwargs', {}))})", ""]
        parts.append(f"**not run**: {res['error']}" if res["error"] else rows_markdown(res["rows"]))
    return "\n".join(parts) + "\n"


def bench(
    quick: bool = False,
    only: str = "",
    out: Path = Path("reports/bench"),
) -> None:
    """Run every benchmark (generation, gen pipeline local vs Ray, EM, inference, memory, segmentation,
    frames, eval protocol) and write reports/bench/bench.md + bench.json.

    --quick runs small sizes (a few minutes on 2 cores). --only takes a comma-separated subset of:
    generation, pipeline, em, inference, memory, segmentation, frames, protocol.
    """
    import typer
    from rich.console import Console

    console = Console(stderr=True)
    names = [n.strip() for n in only.split(",") if n.strip()] or list(SECTIONS)
    unknown = [n for n in names if n not in SECTIONS]
    if unknown:
        raise typer.BadParameter(f"unknown section(s) {unknown}; choose from {list(SECTIONS)}", param_hint="--only")
    results = []
    for name in names:
        with console.status(f"benchmark: {name}{' (quick)' if quick else ''} …"):
            res = run_section(name, quick)
        status = f"[red]failed: {res['error']}" if res["error"] else f"{len(res['rows'])} rows"
        console.print(f"{name}: {status} ({res.get('seconds', 0):.0f} s)")
        results.append(res)
    info = machine_info()
    out.mkdir(parents=True, exist_ok=True)
    md = report_markdown(results, info, quick)
    for path, text in ((out / "bench.md", md), (out / "bench.json", json.dumps(
            {"quick": quick, "machine": info, "sections": results}, indent=2))):
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    print(md)
    console.print(f"wrote {out / 'bench.md'} and {out / 'bench.json'}")
    if any(r["error"] for r in results):
        raise typer.Exit(1)
