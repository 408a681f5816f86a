"""Run every benchmark section and write one report: ``python -m benchmarks.run [--quick] [--only ...]``.

``just bench`` runs this from the repository root. Each section (a module of this folder with a
``run(**kwargs) -> list[dict]`` function) runs in its own Python subprocess (clean peak-memory
figures; the driver never imports bpy) and returns rows of figures. Every figure sits next to a
reference measured in the same run -- the full-covariance GaussianMixture for EM, Blender's own
render for the raster renderer, OpenCV's MOG2 for segmentation, ``cv2.findContours`` for contours,
the local pool for Ray -- and every compute kernel (EM iteration, batched inference) next to its
BLAS floor (:mod:`benchmarks.blas_floor`), so ratios stay meaningful on a shared, noisy machine.
Output: ``<out>/bench.md`` and ``<out>/bench.json`` (every row, the arguments of each section, the
commit and date each section ran at, the machine and the library versions). ``--update`` re-runs the sections
named by ``--only`` and replaces them in the report already at ``<out>``, keeping the others (and the commit and
date they were measured at): a change to one part of the code is measured again without an hour of the rest.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from silpose.shared.atomic import write_json_atomic, write_text_atomic

from . import inputs, subproc


@dataclass(frozen=True)
class Section:
    """One benchmark section: ``name`` (its module ``benchmarks.<name>``, whose ``run`` it calls), its
    full and ``--quick`` arguments, and what it measures (one line for the report)."""

    name: str
    full: dict
    quick: dict
    what: str

    @property
    def module(self) -> str:
        return f"benchmarks.{self.name}"


SECTIONS: dict[str, Section] = {
    "generation": Section(
        "generation", {"n_samples": 200, "memory_samples": 1000},
        {"n_samples": 16, "memory_samples": 0, "shard_size": 8},
        "samples/s per process and on all cores for the raster and Blender renderers; worker RSS growth",
    ),
    "motion": Section(
        "motion", {"n_samples": 200}, {"n_samples": 16, "synthetic_frames": 60, "shard_size": 8},
        "generation with poses from motion-capture clips (BVH, retargeted) and from the bundled motion library "
        "(the motions preset) vs the procedural walk: ms per sample, and the one-off Blender import of the clips",
    ),
    "pipeline": Section(
        "pipeline", {"n_samples": 1000, "workers": 2},
        {"n_samples": 40, "workers": 2, "executors": ["local"]},
        "the whole `silpose gen` pipeline (shards, manifest) on the local spawn pool vs Ray (local instance, "
        "startup included); arrays compared",
    ),
    "contours": Section(
        "contours", {"n_samples": 200}, {"n_samples": 40, "repeats": 2},
        "contour extraction per 4-view sample (320x240 stick figures) vs cv2.findContours",
    ),
    "em": Section(
        "em", {},
        {"n": 2000, "d": 417, "q": 10, "m": 3, "gmm_iters": 1, "n_init": 1, "iter_runs": 3},
        "MPPCA EM per iteration (vs its BLAS floor) and full fit vs sklearn GaussianMixture(full); "
        "held-out log-lik; peak memory",
    ),
    "em_scale": Section(
        "em_scale", {},
        {"n": 3000, "d": 300, "q": 8, "m": 70, "shard_rows": 500, "n_test": 500, "max_iter": 5, "init_rows": 1000,
         "compare_shards": 1},
        "MPPCA streaming fit at the motions scale (N 100k, d 1657, M 200, sparse E-step): total time, time per "
        "iteration vs the exact E-step, peak RSS",
    ),
    "inference": Section(
        "inference", {}, {"frames": 2000, "repeats": 1, "latency_calls": 50, "big_components": 50, "big_frames": 200},
        "batched frames/s (4, 3, 1 views) and single-frame latency of ShapeStructureModel.infer vs its BLAS floor",
    ),
    "memory": Section(
        "memory",
        {"data": "data/paper", "repeats": [1, 2, 4], "modes": ["memory", "stream"], "max_iter": 1, "fallback": "skip"},
        {"data": "data/default", "repeats": [1, 2], "modes": ["memory", "stream"], "n_components": 2,
         "n_latent": 10, "max_iter": 1, "fallback": "tiny"},
        "peak RSS of the in-memory vs streaming (out-of-core) MPPCA fit; dataset repeated 1x/2x/4x at fixed shard size",
    ),
    "segmentation": Section(
        "segmentation", {"n_frames": 200}, {"n_frames": 40, "n_background": 20, "hd_frames": 8},
        "background subtraction frames/s per core at 320x240 vs OpenCV MOG2; at 1920x1080 through the working size",
    ),
    "frames": Section(
        "frames", {"n_frames": 200, "n_background": 50, "fallback": "skip"},
        {"n_frames": 16, "n_background": 10, "fallback": "tiny"},
        "frames -> joints (4 cameras) time steps/s: PNG reading, segmentation, contours, inference "
        "(frames composited from the dataset's test masks, with its trained model)",
    ),
    "recordings": Section(
        # --quick keeps the full recording (150 frames, the full-size lab model): on a 30-frame clip the run's
        # set-up was most of its time, so the time steps/s said little about a recording (silpose infer's use)
        "recordings", {"n_frames": 150, "repeat": 10, "train": 400, "colour_frames": 150},
        {"n_frames": 150, "repeat": 3, "train": 400, "n_points": 200, "colour_frames": 150},
        "silpose infer --videos on the lab recording (4 cameras 644x486, mask videos): time steps/s, CPU per step, "
        "peak RSS on 1x vs a repeat-x longer video; accuracy vs truth and clean masks; occupancy grid vs foot points",
    ),
    "identities": Section(
        "identities", {"n_frames": 200}, {"n_frames": 60, "colour": False},
        "ids and identity switches of four walkers of different statures crossing (lab recording, mask and colour "
        "videos), with and without the per-person appearance model",
    ),
    "protocol": Section(
        "protocol", {"n_test": 500, "fallback": "skip"},
        {"n_test": 40, "experiments": ["E2", "E4"], "fallback": "tiny"},
        "the evaluation protocol (silpose eval): seconds per experiment on a dataset with its trained model",
    ),
}

LEGEND = (
    "Each figure has its reference measured in the same run; the machine is shared, so absolute timings "
    "are noisy and the ratios are the figures to compare. Compute kernels also carry `blas_floor_s`, the "
    "time plain numpy takes for the matrix products the kernel cannot avoid at the row's shapes "
    "(`floor_products`; see benchmarks/blas_floor.py), and `over_floor` = kernel seconds / floor seconds."
)


def parse_set(items: list[str]) -> dict[str, dict]:
    """``["em.n=5000", "memory.data=data/paper"]`` -> ``{"em": {"n": 5000}, "memory": {"data": "data/paper"}}``.

    A value is read as JSON when it parses (numbers, lists, true/false), else kept as a string.
    """
    out: dict[str, dict] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        section, dot, name = key.partition(".")
        if not sep or not dot or not name:
            raise ValueError(f"--set {item!r}: expected SECTION.KEY=VALUE")
        if section not in SECTIONS:
            raise ValueError(f"--set {item!r}: unknown section {section!r}; choose from {', '.join(SECTIONS)}")
        try:
            value = json.loads(raw)
        except json.JSONDecodeError:
            value = raw
        out.setdefault(section, {})[name] = value
    return out


def run_section(name: str, quick: bool, overrides: dict | None = None, env: dict | None = None) -> dict:
    """Run one section in a subprocess; returns {section, what, module, kwargs, rows, seconds, error, commit,
    date} (the commit checked out and the time the section started)."""
    sec = SECTIONS[name]
    kwargs = {**(sec.quick if quick else sec.full), **(overrides or {})}
    started = _now()
    res = subproc.call(sec.module, "run", kwargs, env=env)
    return {"section": name, "what": sec.what, "module": sec.module, "kwargs": kwargs,
            "rows": res.value if res.error is None else [], "seconds": res.seconds, "error": res.error,
            "commit": _git_commit(), "date": started}


def _now() -> str:
    return time.strftime("%Y-%m-%d %H:%M:%S %Z")


def load_report(path: Path) -> dict:
    """A ``bench.json`` this runner wrote, checked: {quick, machine, sections}. Raises ValueError naming the file
    and the field that is wrong."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"{path}: no report to update (run without --update first)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a readable JSON report ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object")
    if not isinstance(data.get("quick"), bool):
        raise ValueError(f"{path}: field 'quick' must be true or false")
    if not isinstance(data.get("machine"), dict):
        raise ValueError(f"{path}: field 'machine' must be an object")
    sections = data.get("sections")
    if not isinstance(sections, list) or not all(isinstance(s, dict) and s.get("section") in SECTIONS
                                                   and isinstance(s.get("rows"), list) for s in sections):
        raise ValueError(f"{path}: field 'sections' must be a list of sections, each with a known 'section' name "
                         "and a list of 'rows'")
    return data


def merge_sections(old: dict, new: list[dict]) -> list[dict]:
    """The sections of the report ``old`` with those of ``new`` in place of their namesakes, in the order of
    :data:`SECTIONS`. Old sections without their own commit and date (reports written before they were recorded)
    get the old report's machine's."""
    by_name = {}
    for sec in old["sections"]:
        sec = dict(sec)
        sec.setdefault("commit", old["machine"].get("commit"))
        sec.setdefault("date", old["machine"].get("date"))
        by_name[sec["section"]] = sec
    by_name.update({sec["section"]: sec for sec in new})
    return [by_name[name] for name in SECTIONS if name in by_name]


def _git_commit() -> str | None:
    try:
        out = subprocess.run(["git", "-C", str(subproc.ROOT), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def machine_info() -> dict:
    """The machine (CPU, cores, load), the BLAS numpy uses, and the versions of Python and the libraries."""
    import numpy
    from threadpoolctl import threadpool_info

    info = {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "load_average": [round(x, 2) for x in os.getloadavg()],
        "date": _now(),
        "commit": _git_commit(),
        "numpy": numpy.__version__,
    }
    try:
        with open("/proc/cpuinfo") as fh:
            info["cpu"] = next((ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), "?")
    except OSError:
        pass
    blas = [lib for lib in threadpool_info() if lib.get("user_api") == "blas"]
    if blas:
        info["blas"] = f"{blas[0]['internal_api']} {blas[0]['version']} ({blas[0]['num_threads']} threads)"
    for pkg in ("scipy", "scikit-learn", "pyarrow", "opencv-python-headless", "bpy", "ray", "silpose-model"):
        try:
            info[pkg] = version(pkg)
        except PackageNotFoundError:
            pass
    return info


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list):
        return "[" + ", ".join(_fmt(v) for v in value[:6]) + (", …" if len(value) > 6 else "") + "]"
    return "" if value is None else str(value).replace("|", "/")


def rows_markdown(rows: list[dict]) -> str:
    """Markdown table over the union of the rows' keys (first-seen order; ``rss_curve_mb`` left out)."""
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys and k != "rss_curve_mb"]
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(_fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


def report_markdown(results: list[dict], info: dict, quick: bool) -> str:
    """The whole report: machine line, legend, one table per section (or why it did not run)."""
    parts = ["# silpose benchmarks" + (" (quick)" if quick else ""), "",
             "Machine: " + ", ".join(f"{k} {v}" for k, v in info.items()), "", LEGEND]
    for res in results:
        when = f", commit {res['commit']}, {res['date']}" if res.get("commit") or res.get("date") else ""
        parts += ["", f"## {res['section']}", "", f"{res['what']} (`{res['module']}`, {res['seconds']:.0f} s, "
                  f"arguments {json.dumps(res['kwargs'])}{when})", ""]
        parts.append(f"**failed**: {res['error']}" if res["error"] else rows_markdown(res["rows"]))
    return "\n".join(parts) + "\n"


def build_parser() -> argparse.ArgumentParser:
    names = ", ".join(SECTIONS)
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.run",
        description="Run the silpose benchmarks (each section in its own subprocess) and write "
                    "<out>/bench.md and <out>/bench.json. Exit status 1 if a section failed.",
    )
    ap.add_argument("--quick", action="store_true",
                    help="small sizes (a few minutes on 2 cores); sections that need a dataset and model "
                         "generate a tiny one in a temporary folder when data/default is missing "
                         "(full runs report them as skipped instead)")
    ap.add_argument("--only", default="", metavar="SECTIONS",
                    help=f"comma-separated subset of the sections, run in this order: {names} (default: all)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="override one argument of a section's run() (VALUE read as JSON when it parses), e.g. "
                         "--set memory.data=data/paper --set 'memory.repeats=[1,2,4]'; repeatable")
    ap.add_argument("--out", type=Path, default=Path("reports/bench"),
                    help="folder for bench.md and bench.json (default: reports/bench)")
    ap.add_argument("--update", action="store_true",
                    help="re-run only the --only sections and replace them in the report already in --out, keeping "
                         "the other sections as they were measured (each keeps its commit and date); the sizes "
                         "(--quick or not) must match that report's")
    ap.add_argument("--list", action="store_true", help="list the sections and their arguments, then exit")
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    if args.list:
        for name, sec in SECTIONS.items():
            print(f"{name}: {sec.what}\n    full {json.dumps(sec.full)}\n    quick {json.dumps(sec.quick)}")
        return 0
    names = [n.strip() for n in args.only.split(",") if n.strip()] or list(SECTIONS)
    unknown = [n for n in names if n not in SECTIONS]
    if unknown:
        ap.error(f"--only: unknown section(s) {', '.join(unknown)}; choose from {', '.join(SECTIONS)}")
    try:
        overrides = parse_set(args.overrides)
    except ValueError as exc:
        ap.error(str(exc))
    old = None
    if args.update:
        if not args.only.strip():
            ap.error("--update needs --only: the sections to measure again")
        try:
            old = load_report(args.out / "bench.json")
        except ValueError as exc:
            ap.error(str(exc))
        if old["quick"] != args.quick:
            ap.error(f"--update: {args.out / 'bench.json'} holds {'--quick' if old['quick'] else 'full-size'} "
                     f"figures; run with{'' if old['quick'] else 'out'} --quick to update it")
    results = []
    with tempfile.TemporaryDirectory(prefix="silpose-bench-tiny-") as tiny:
        env = {**os.environ, inputs.CACHE_ENV: tiny}  # tiny inputs made once, shared by the sections
        for name in names:
            print(f"benchmark: {name}{' (quick)' if args.quick else ''} ...", file=sys.stderr, flush=True)
            res = run_section(name, args.quick, overrides.get(name), env)
            skipped = [r["skipped"] for r in res["rows"] if "skipped" in r]
            status = f"FAILED: {res['error']}" if res["error"] else (skipped[0] if skipped else f"{len(res['rows'])} rows")
            print(f"{name}: {status} ({res['seconds']:.0f} s)", file=sys.stderr, flush=True)
            results.append(res)
    info = machine_info()
    if old is not None:
        results = merge_sections(old, results)
    md = report_markdown(results, info, args.quick)
    write_text_atomic(args.out / "bench.md", md)
    write_json_atomic(args.out / "bench.json", {"quick": args.quick, "machine": info, "sections": results})
    print(md)
    print(f"wrote {args.out / 'bench.md'} and {args.out / 'bench.json'}", file=sys.stderr)
    return 1 if any(r["error"] for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
