"""Write docs/results.md from the reports, and refresh the README's generated tables.

    python docs/results.py [--reports reports] [--out docs/results.md] [--readme README.md] [--only bench]   (just results)

Every figure comes from a file a command wrote, never from a hand-copied number:
``reports/<preset>/headline.json`` (``silpose eval``), the training report next to the model the evaluation
read (``<model>.report.json``, ``silpose train``) and ``reports/bench/bench.json`` (``just bench``). A preset
without a report gets "not measured" in its column. The README gets the short results table, the speed table and the table of
calibration formats (from ``silpose.app.rig.formats.FORMATS``) between ``<!-- NAME:start -->`` and
``<!-- NAME:end -->`` markers.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PRESETS = ("default", "paper")  # columns always shown; other report folders are added after them
NOT_MEASURED = "not measured"


def load_reports(reports: Path) -> dict[str, dict]:
    """``{name: headline}`` of every ``<reports>/<name>/headline.json``, the presets first."""
    found = {}
    for path in sorted(reports.glob("*/headline.json")):
        try:
            found[path.parent.name] = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            print(f"results: skipping {path} ({exc})", file=sys.stderr)
            continue
        seq = path.with_name("sequences.json")  # E7 (silpose.eval.sequences), kept beside the headline
        if seq.is_file():
            try:
                found[path.parent.name]["sequences"] = json.loads(seq.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                print(f"results: skipping {seq} ({exc})", file=sys.stderr)
    names = [p for p in PRESETS] + [n for n in found if n not in PRESETS]
    return {n: found.get(n) for n in names}


def training_report(head: dict | None) -> dict | None:
    """The training report of the model an evaluation read (``<model>.report.json``), if it is still there."""
    model = (head or {}).get("settings", {}).get("model")
    if not model:
        return None
    path = Path(model).with_suffix(".report.json")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _get(d, *keys):
    for k in keys:
        if isinstance(d, list):
            d = next((x for x in d if k(x)), None) if callable(k) else (d[k] if k < len(d) else None)
        elif isinstance(d, dict):
            d = d.get(k)
        else:
            return None
    return d


def _f(v, fmt="{:.2f}"):
    return "–" if v is None else fmt.format(v)


def _flips(h):
    row = _get(h, "e6", "flips", lambda r: r.get("condition") == "4 views, standard")
    if row is None:
        return None
    return f"{row['single_answer_flips_pct']:.1f} % / {row['best_of_3_flips_pct']:.1f} %"


def _missing_view(h):
    rows = _get(h, "e6", "missing_view") or []
    if not rows:
        return None
    mean = lambda k: sum(r[k] for r in rows) / len(rows)  # noqa: E731
    return f"{mean('ratio'):.2f}× / {mean('ratio_robust'):.2f}×"


def _self_intersection(h):
    rows = [r for r in (_get(h, "e6", "self_intersection") or []) if r.get("untangled_pct") is not None]
    if not rows:
        return None
    return " / ".join(f"{r['raw_pct']:.0f} % → {r['untangled_pct']:.1f} %" for r in rows)


def _garbage(h):
    bad = _get(h, "e6", "plausibility", "garbage") or []
    good = _get(h, "e6", "plausibility", "genuine") or []
    if not bad or not good:
        return None
    most = lambda kind: max((r["flagged_pct"] for r in good if r["input"] == f"test, {kind}"), default=None)  # noqa: E731
    return (f"{min(r['flagged_pct'] for r in bad):.0f} % / {_f(most('clean'), '{:.1f} %')} / "
            f"{_f(most('standard'), '{:.1f} %')} / {_f(most('mask mild'), '{:.1f} %')}")


def _sequences(h):
    q = _get(h, "sequences")
    if not q:
        return None
    best = next((k for k in q if k.startswith("best_of_") and k.endswith("_mean_cm")), None)
    return (f"{q['per_frame_mean_cm']:.2f} / {q['temporal_mean_cm']:.2f} / {q[best]:.2f} (flips "
            f"{q['per_frame_flips_pct']:.1f} → {q['temporal_flips_pct']:.1f} %; {q['n_sequences']} sequences)")


def _train(h):
    r = training_report(h)
    if r is None:
        return None
    hp, em = r["hyperparameters"], r["em"]
    return (f"{em['fit_time_s']:.0f} s, {em['n_iter']} EM iterations, M {hp['n_components']}, q {hp['n_latent']}, "
            f"held-out joint error {r['heldout']['joint_error_cm']:.2f} cm")


def _noise(h, noise, method="mppca"):
    return _get(h, "pose_mean_cm_by_noise_all_views", noise, method)


def _baselines(h, n):
    by = _get(h, "pose_mean_cm_by_method_and_n_views", str(n))
    if not by:
        return None
    return " / ".join(_f(by.get(m)) for m in ("mppca", "mppca robust", "knn", "ridge", "mlp"))


#: The baselines of :func:`_ahead`, as the tables name them.
BASELINE_NAMES = {"knn": "kNN", "ridge": "ridge", "mlp": "MLP"}


def _ahead(h):
    """Where a baseline's error is below the MPPCA's posterior mean (1-4 views, standard noise): each such number
    of views with the baselines ahead, their error against the posterior mean's (and the robust answer's, where it
    was measured); "none" when the MPPCA leads everywhere."""
    by = _get(h, "pose_mean_cm_by_method_and_n_views")
    if not by:
        return None
    parts = []
    for n in sorted(by, key=int, reverse=True):
        row = by[n]
        ref = row.get("mppca")
        if ref is None:
            continue
        better = [f"{name} {row[k]:.2f}" for k, name in BASELINE_NAMES.items() if row.get(k) is not None and row[k] < ref]
        if better:
            robust = f" (robust {row['mppca robust']:.2f})" if row.get("mppca robust") is not None else ""
            parts.append(f"{n} view{'s' if n != '1' else ''}: " + ", ".join(better) + f" vs {ref:.2f}{robust}")
    return "; ".join(parts) if parts else "none (1–4 views)"


def _mlp_cost(h):
    t = _get(h, "baseline_timing", "mlp")
    if not t:
        return None
    return f"{t['fit_s']:.0f} s / {t['ms_per_frame']:.2f} ms (kNN {_f(_get(h, 'baseline_timing', 'knn', 'ms_per_frame'))} ms)"


#: (label, value(headline) -> str | None, the paper's figure) — the rows of docs/results.md.
ROWS = [
    ("4 / 3 / 2 / 1 views, standard noise, posterior mean (cm)",
     lambda h: None if _get(h, "pose_cm_by_n_views") is None else " / ".join(
         _f(_get(h, "pose_cm_by_n_views", str(k), "mean")) for k in (4, 3, 2, 1)),
     lambda p: f"{p['pose_4_views_cm']:g} / – / – / {p['pose_1_view_cm']:g}"),
    ("4 views, standard noise, robust inference (`silpose infer`'s default)",
     lambda h: _f(_noise(h, "standard", "mppca robust")) if _noise(h, "standard", "mppca robust") else None, None),
    ("4 views, clean contours",
     lambda h: _f(_noise(h, "clean")) if _noise(h, "clean") else None, None),
    ("4 views, mask-level noise (holes, blobs, a shadow), robust: mild / strong",
     lambda h: None if _noise(h, "mask mild", "mppca robust") is None else
     f"{_noise(h, 'mask mild', 'mppca robust'):.2f} ({_noise(h, 'mask mild', 'x_clean_robust'):.2f}× clean) / "
     f"{_noise(h, 'mask strong', 'mppca robust'):.2f}", None),
    ("kNN, 4 views: standard / mask mild / mask strong",
     lambda h: None if _noise(h, "standard", "knn") is None else " / ".join(
         _f(_noise(h, n, "knn")) for n in ("standard", "mask mild", "mask strong")), None),
    ("front/back flips, 4 views, standard noise: single answer / best of 3", _flips, None),
    ("recordings (test clips, or walkers, played for 1 s at 30 fps), 4 views, robust: each frame alone / chosen "
     "along the frames (`silpose infer`'s answer for one person) / best of 8 hypotheses (cm)", _sequences, None),
    ("4 views, standard noise: posterior mean / robust / kNN / ridge / MLP (cm)", lambda h: _baselines(h, 4), None),
    ("1 view (each view alone, their mean), standard noise: posterior mean / robust / kNN / ridge / MLP (cm)",
     lambda h: _baselines(h, 1), None),
    ("where a baseline beats the MPPCA's posterior mean, standard noise (baseline vs posterior mean (robust); cm)",
     _ahead, None),
    ("MLP baseline: fitting time / time per frame", _mlp_cost, None),
    ("chance (a random training pose, cm)",
     lambda h: _f(_get(h, "chance_cm", "mean"), "{:.1f}") if _get(h, "chance_cm") else None,
     lambda p: f"{p['chance_cm']:g}"),
    ("multi-view vs single-view training, pose: equal q / equal latent dimensions per view",
     lambda h: None if _get(h, "e1") is None else
     f"{_get(h, 'e1', 'pose_improvement_pct'):.0f} % / {_get(h, 'e1_equal_q_per_view', 'pose_improvement_pct'):.0f} % "
     "better", lambda p: f"{p['multi_view_pose_improvement_pct']:g} %"),
    ("the same, contours (mean Chamfer)",
     lambda h: None if _get(h, "e1") is None else
     f"{_get(h, 'e1', 'contour_improvement_pct'):.1f} % / "
     f"{_get(h, 'e1_equal_q_per_view', 'contour_improvement_pct'):.1f} % better",
     lambda p: f"{p['multi_view_contour_improvement_pct']:g} %"),
    ("Chamfer, true → reconstruction, 4 / 1 views (px)",
     lambda h: None if _get(h, "chamfer_px_by_n_views") is None else
     f"{_get(h, 'chamfer_px_by_n_views', '4', 'mean'):.2f} / {_get(h, 'chamfer_px_by_n_views', '1', 'mean'):.2f}",
     None),
    ("a missing view's contour from the other three vs the nearest training sample's: posterior mean / robust",
     _missing_view, None),
    ("reconstructed contours that self-intersect, before → after untangling (4 views / a missing view)",
     _self_intersection, None),
    ("flagged implausible: non-person inputs (fewest) / genuine test inputs, clean, standard noise, mild mask "
     "noise (most, over 1-4 views)", _garbage, None),
    ("`silpose train` (the evaluated model's training report)", _train, None),
    ("`silpose eval` time (s)",
     lambda h: None if _get(h, "timings_s") is None else f"{sum(_get(h, 'timings_s').values()):.0f}", None),
]

#: The README's short table: (label, row index in ROWS).
README_ROWS = [0, 1, 3, 6, 7, 8, 9, 11]


def results_table(reports: dict[str, dict | None], rows=None) -> str:
    names = list(reports)
    paper = next((h["paper"] for h in reports.values() if h and "paper" in h), None)
    picked = [ROWS[i] for i in rows] if rows is not None else ROWS
    lines = ["| | " + " | ".join(f"`{n}` preset" for n in names) + " | paper |",
             "|---|" + "---|" * (len(names) + 1)]
    for label, value, paper_value in picked:
        cells = []
        for n in names:
            h = reports[n]
            v = value(h) if h else None
            cells.append(v if v is not None else NOT_MEASURED)
        p = paper_value(paper) if paper_value and paper else "–"
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {p} |")
    return "\n".join(lines)


def bench_section(bench: Path) -> list[str]:
    try:
        data = json.loads(bench.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return ["Not measured: run `just bench` (writes `reports/bench/bench.json`), then `just results`.", ""]
    sys.path.insert(0, str(ROOT))
    from benchmarks.run import rows_markdown

    size = ("`--quick`: small sizes, so ratios against the BLAS floor are those of small products, not of the full "
            "sizes `just bench` measures" if data.get("quick") else "full sizes")
    if overrides(data):
        size += f"; arguments set for this run: {overrides(data)}"
    commits = {sec.get("commit") for sec in data.get("sections", [])}
    machine = "Machine: " if len(commits) <= 1 else ("Machine, at the last of the runs (`just bench --update` "
                                                      "re-measured some sections; each names its commit): ")
    out = [f"Run: {size}.", "", machine + ", ".join(f"{k} {v}" for k, v in data.get("machine", {}).items()), ""]
    for sec in data.get("sections", []):
        when = f" Measured at commit {sec['commit']}, {sec.get('date', '?')}." if sec.get("commit") else ""
        what = sec.get("what", "")
        out += [f"### {sec['section']}", "", (what.rstrip(".") + "." if when else what) + when, ""]
        out.append(f"failed: {sec['error']}" if sec.get("error") else rows_markdown(sec.get("rows", [])))
        out.append("")
    return out


def _rows(data: dict, section: str) -> list[dict]:
    return next((s.get("rows", []) for s in data.get("sections", []) if s.get("section") == section), [])


def _row(rows: list[dict], **match) -> dict | None:
    """The first row whose fields start with the given values (strings) or equal them (other values)."""
    for r in rows:
        if all((isinstance(v, str) and str(r.get(k, "")).startswith(v)) or r.get(k) == v for k, v in match.items()):
            return r
    return None


def _segmentation_cell(rows: list[dict], method: str, contains: str = "") -> str | None:
    r = next((r for r in rows if str(r.get("method", "")).startswith(method) and contains in str(r["method"])), None)
    ref = _row(rows, method=(r or {}).get("same_size_mog2") or "\0")
    if not r or not ref or r.get("time_vs_same_size_mog2") is None:
        return None
    return f"{r['time_vs_same_size_mog2']:.2f}× MOG2's CPU time, IoU {r['iou']:.3f} vs {ref['iou']:.3f}"


def speed_rows(data: dict) -> list[tuple[str, str | None]]:
    """The headline speed figures of a ``bench.json`` as (what, figure or None when the row is missing)."""
    rec, seg, inf = _rows(data, "recordings"), _rows(data, "segmentation"), _rows(data, "inference")
    ids = _rows(data, "identities")
    out = []
    plain = [r for r in rec if r.get("name") == "run" and re.fullmatch(r"\d+x", str(r.get("run", "")))]
    masks = max(plain, key=lambda r: r.get("steps", 0), default=None)  # the longest plain run (1x, repeat x)
    out.append(("4 mask videos, 644×486 → joints, no overlays", masks and
                f"{masks['steps_per_s']:.1f} time steps/s over {masks['steps']} steps "
                f"({masks['steady_steps_per_s']:.0f} after the set-up)"))
    for colour in (r for r in rec if r.get("name") == "run" and str(r.get("run", "")).startswith("colour")
                   and "overlays" not in str(r.get("run"))):
        size = str(colour["run"]).split()[-1].replace("x", "×")
        out.append((f"4 colour videos, {size} → joints, no overlays",
                    f"{colour['steps_per_s']:.1f} time steps/s over {colour['steps']} steps "
                    f"({colour['steady_steps_per_s']:.0f} after the {colour['setup_s']:.1f} s set-up)"))
    ov_m = [r for r in rec if r.get("name") == "run" and re.fullmatch(r"\d+x with overlays", str(r.get("run", "")))
            and "overlay_share_wall" in r]
    ov_c = next((r for r in rec if str(r.get("run", "")).startswith("colour") and "overlays" in str(r.get("run"))
                 and "overlay_share_wall" in r), None)

    def share(r: dict) -> str:
        # wall: what the overlays add to the run's duration (drawn in a worker process beside it; below 0 is the
        # runs' noise); CPU: what they cost the machine
        return f"{100 * r['overlay_share_wall']:.0f} % ({100 * r['overlay_share_cpu']:.0f} %)"

    masks_share = " and ".join(f"{share(r)} over {r['steps']} steps" for r in sorted(ov_m, key=lambda r: r["steps"]))
    out.append(("overlay videos' share of a run: wall time (CPU time), masks / colour",
                f"{masks_share} / {share(ov_c)} over {ov_c['steps']} steps" if ov_m and ov_c else None))
    idr = _row(ids, input="mask videos", tracker="appearance")
    apart = _row(ids, input="mask videos, walkers apart", tracker="appearance")
    out.append(("4 walkers, mask videos: ids / identity switches passing through each other; walking apart "
                "(joints inside their own silhouette)",
                idr and f"{idr['ids']} / {idr['identity_switches']} over {idr['frames']} steps"
                + (f"; {apart['ids']} / {apart['identity_switches']} ({apart['joints_inside']:.3f})"
                   if apart and apart.get("joints_inside") is not None else "")))
    fit = _row(rec, name="accuracy", input="recording (lossy mask videos)")
    unfit = _row(rec, name="accuracy", input="recording, without the silhouette fit")
    out.append(("2 walkers (mask videos): joints inside their own silhouette in the views used, fitted / not",
                fit and unfit and fit.get("joints_inside") is not None and unfit.get("joints_inside") is not None
                and f"{fit['joints_inside']:.3f} / {unfit['joints_inside']:.3f}"))
    out.append(("segmentation, 320×240, vs OpenCV's MOG2 on the same frames",
                _segmentation_cell(seg, "BackgroundModel.segment (streaming)")))
    out.append(("segmentation, full HD shrunk to the working size, vs MOG2 at that size",
                _segmentation_cell(seg, "1920x1080: BackgroundModel at the working size")))
    out.append(("segmentation, full HD at full size, vs MOG2", _segmentation_cell(seg, "1920x1080: BackgroundModel at full")))
    rendered = next((r for r in seg if str(r.get("method", "")).startswith("rendered frames ")
                     and "BackgroundModel" in str(r["method"])), None)
    size = str(rendered["method"]).split()[2].replace("x", "×") + ", " if rendered else ""
    out.append((f"segmentation, {size}frames rendered by Blender (textured room, shadows), vs MOG2",
                _segmentation_cell(seg, "rendered frames ", "BackgroundModel")))
    plain = _row(inf, case="batched, 4 views (joints")
    robust = _row(inf, case="batched, 4 views, robust (")
    out.append(("inference, 4 views, batched: plain / robust, × the BLAS floor", plain and robust and
                f"{plain['over_floor']:.1f}× / {robust['over_floor']:.1f}× "
                f"({plain['value']:,.0f} / {robust['value']:,.0f} frames/s)"))
    one = _row(inf, case="single frame, 4 views, robust, M")
    out.append(("inference, one frame, robust, " + (one["case"].split("robust, ")[-1] if one else "M 50 q 40"),
                one and f"{one['value']:.1f} ms"))
    return out


def overrides(data: dict) -> str:
    """The ``--set`` arguments a ``bench.json`` was run with: each section's arguments that differ from the
    defaults of its size (``benchmarks.run.SECTIONS``), as ``section: key value, ...; ...``; "" when none."""
    sys.path.insert(0, str(ROOT))
    from benchmarks.run import SECTIONS

    parts = []
    for sec in data.get("sections", []):
        known = SECTIONS.get(sec.get("section"))
        if known is None:
            continue
        base = known.quick if data.get("quick") else known.full
        diff = {k: v for k, v in (sec.get("kwargs") or {}).items() if base.get(k, None) != v}
        if diff:
            parts.append(f"{sec['section']}: " + ", ".join(f"{k} {v}" for k, v in diff.items()))
    return "; ".join(parts)


def speed_table(bench: Path) -> str:
    """The README's speed table from ``bench.json``; says how to measure when there is none."""
    try:
        data = json.loads(bench.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return "Not measured: `just bench`, then `just results`."
    m = data.get("machine", {})
    size = "`just bench --quick`" if data.get("quick") else "`just bench`"
    if overrides(data):
        size += f" ({overrides(data)})"
    load = m.get("load_average") or ["?"]
    lines = [f"| {size}: {m.get('cpu_count', '?')} cores, {m.get('cpu', '?')}, {m.get('blas', '?')}, load {load[0]} "
             "| measured |", "|---|---|"]
    lines += [f"| {what} | {fig if fig is not None else NOT_MEASURED} |" for what, fig in speed_rows(data)]
    return "\n".join(lines)


def group_section(reports: dict[str, dict | None]) -> list[str]:
    """Per activity group (``by_group`` of a report whose test set comes from the motion library)."""
    out = []
    for name, h in reports.items():
        groups = (h or {}).get("by_group")
        if not groups:
            continue
        out += [f"### `{name}`: per activity group of the held-out test clips", "",
                "| group | test samples | 4 / 3 / 2 / 1 views, posterior mean | 4 views, robust | kNN / MLP, 4 views |",
                "|---|---|---|---|---|"]
        for g, e in groups.items():
            by = e.get("pose_cm_by_n_views", {})
            views = " / ".join(_f(by.get(str(k))) for k in (4, 3, 2, 1))
            base = e.get("baselines_cm_all_views", {})
            out.append(f"| {g} | {e.get('n_test', '?')} | {views} | {_f(e.get('robust_cm_all_views'))} | "
                       f"{_f(base.get('knn'))} / {_f(base.get('mlp'))} |")
        out.append("")
    return out


def sequences_section(reports: dict[str, dict | None]) -> list[str]:
    """Per activity group, E7's recordings (``silpose.eval.sequences``): each frame alone vs chosen along the frames."""
    out = []
    for name, h in reports.items():
        q = _get(h, "sequences") if h else None
        if not q or not q.get("by_group"):
            continue
        best = next(k for k in q if k.startswith("best_of_") and k.endswith("_mean_cm"))
        out += [f"`{name}`: {q['n_sequences']} sequences of {q['length']} frames, {q['frames_scored']} frames scored "
                f"({q['inference']}, {q['noise']} noise); cm.", "",
                "| group | frames | each frame alone | chosen along the frames | best of the hypotheses |",
                "|---|---|---|---|---|"]
        for g, v in q["by_group"].items():
            out.append(f"| {g} | {v['frames']} | {v['per_frame_mean_cm']:.2f} | {v['temporal_mean_cm']:.2f} | "
                       f"{v[best]:.2f} |")
        out.append("")
    return out


def curve_table(path: Path) -> list[str]:
    """One ``learning_curve.json`` (``python -m silpose.eval.learning_curve``) as an N x M table of the
    error with every view / one view (cm); [] when it cannot be read or has no rows."""
    try:
        rows = json.loads(path.read_text(encoding="utf-8")).get("rows", [])
    except (OSError, ValueError):
        return []
    if not rows:
        return []
    ms = sorted({r["n_components"] for r in rows})
    ns = sorted({r["n_samples"] for r in rows})
    out = ["| training samples \\ components | " + " | ".join(str(m) for m in ms) + " |", "|---|" + "---|" * len(ms)]
    for n in ns:
        cells = []
        for m in ms:
            r = next((r for r in rows if r["n_samples"] == n and r["n_components"] == m), None)
            cells.append("–" if r is None else f"{r['pose_all_views_cm']:.2f} / {r['pose_1_view_cm']:.2f}")
        out.append(f"| {n:,} | " + " | ".join(cells) + " |")
    return out


def learning_curve_section(reports_dir: Path) -> list[str]:
    """Every ``<reports>/<name>/learning_curve.json`` as a table, with its settings."""
    out = []
    for path in sorted(reports_dir.glob("*/learning_curve.json")):
        table = curve_table(path)
        if not table:
            continue
        data = json.loads(path.read_text(encoding="utf-8"))
        st, first = data.get("settings", {}), data["rows"][0]
        w = f", structure weight {st['structure_weight']:g}" if "structure_weight" in st else ""
        out += [f"### `{path.parent.name}` (data `{st.get('data', '?')}`, q {first.get('n_latent', '?')}{w}, "
                f"{first.get('n_test', '?')} test samples): every view / one view, cm", ""] + table
        fits = ", ".join(f"N {r['n_samples']:,} M {r['n_components']}: {r['fit_s']:.0f} s"
                         for r in data["rows"])
        out += ["", f"Fit times (EM {st.get('fit', 'streaming')}, wall, shared machine): {fits}.", ""]
    return out


def coverage_section(reports_dir: Path) -> list[str]:
    """Every ``<reports>/<name>/coverage.json`` (``silpose eval``; ``python -m silpose.eval.coverage``): the error of
    the nearest training pose, overall and per activity group, and the model's error on samples it was fitted on
    beside its test error (``silpose.eval.in_sample``) when the report has them."""
    out = []
    for path in sorted(reports_dir.glob("*/coverage.json")):
        try:
            c = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        groups = c.get("groups") or {}
        out += [f"`{path.parent.name}`: the nearest of {c['n_train']:,} training poses to each of {c['n_test']} test "
                f"poses is {c['mean_cm']:.2f} cm off on average (median {c['median_cm']:.2f}): no answer drawn from "
                "the training poses does better.", ""]
        m = c.get("model")
        if m:
            out += [f"The model ({m['inference']}, {m['noise']} noise) on {m['n']} of the samples it was fitted on: "
                    f"{m['in_sample_mean_cm']:.2f} cm (median {m['in_sample_median_cm']:.2f}); on the test poses: "
                    f"{m['test_mean_cm']:.2f} cm (median {m['test_median_cm']:.2f}). The first is what the model leaves on "
                    "poses and bodies it has seen; the difference is what the test poses' distance from the training "
                    "poses costs (`silpose.eval.in_sample`).", ""]
        if groups:
            out += ["| group | " + " | ".join(groups) + " |", "|---|" + "---|" * len(groups),
                    "| nearest training pose, cm | " + " | ".join(f"{g['mean_cm']:.2f}" for g in groups.values()) + " |",
                    ""]
    return out


def results_markdown(reports: dict[str, dict | None], bench: Path) -> str:
    measured = [n for n, h in reports.items() if h]
    parts = [
        "# Results", "",
        "Generated by `docs/results.py` (`just results`) from `reports/<preset>/headline.json` (`silpose eval`), the",
        "evaluated model's training report and `reports/bench/bench.json` (`just bench`); do not edit by hand.",
        f"Reports found: {', '.join(f'`{n}`' for n in measured) or 'none'}.", "",
        "Pose error: mean Euclidean distance over the 19 joints, cm, root-relative, no other alignment. The test",
        "walkers have other builds and clothing than the training ones. Standard test noise: 1 px jitter and 6",
        "contour patches of 30 points, 8 px deep, per view. Each report's `summary.md` has every table and figure.",
        "", "## Pose and contours", "", results_table(reports), "",
    ]
    for n in measured:
        s = reports[n].get("settings", {})
        parts += [f"`{n}`: {s.get('n_train', '?')} training samples (with augmentation), {s.get('n_test', '?')} test "
                  f"walkers, {s.get('n_views', '?')} views; data `{s.get('data', '?')}`, model `{s.get('model', '?')}`"
                  + (f", silpose {reports[n]['silpose_version']}" if reports[n].get("silpose_version") else "") + ".",
                  ""]
    groups = group_section(reports)
    if groups:
        parts += ["## Motions: per activity group", ""] + groups
    seq = sequences_section(reports)
    if seq:
        parts += ["## Recordings: each frame alone and chosen along the frames, per activity group", ""] + seq
    cover = coverage_section(bench.parent.parent)
    if cover:
        parts += ["## Pose coverage: the nearest training pose (an oracle) and the model on its own samples", ""] + cover
    curve = learning_curve_section(bench.parent.parent)
    if curve:
        parts += ["## Learning curve (posterior mean, standard noise)", ""] + curve
    return "\n".join(parts).rstrip() + "\n\n" + benchmarks_markdown(bench)


def replace_block(text: str, name: str, body: str) -> str:
    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    if start not in text or end not in text:
        raise SystemExit(f"results: README has no {start} ... {end} block")
    head, rest = text.split(start, 1)
    return head + start + "\n" + body.strip() + "\n" + end + rest.split(end, 1)[1]


#: The heading from which docs/results.md holds the benchmarks (``--only bench`` rewrites from it on).
BENCH_HEADING = "## Benchmarks"


def benchmarks_markdown(bench: Path) -> str:
    """docs/results.md's benchmark part (from :data:`BENCH_HEADING` to the end) from ``bench.json``."""
    return "\n".join([BENCH_HEADING, "", "### Summary", "", speed_table(bench), ""] + bench_section(bench)).rstrip() + "\n"


def replace_benchmarks(text: str, bench: Path) -> str:
    """``text`` (docs/results.md) with its benchmark part rewritten from ``bench.json``, the rest kept."""
    if f"\n{BENCH_HEADING}\n" not in text:
        raise SystemExit(f"results: docs/results.md has no '{BENCH_HEADING}' heading")
    return text.split(f"\n{BENCH_HEADING}\n", 1)[0] + "\n" + benchmarks_markdown(bench)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reports", type=Path, default=ROOT / "reports")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results.md")
    ap.add_argument("--readme", type=Path, default=ROOT / "README.md")
    ap.add_argument("--only", choices=("all", "bench"), default="all",
                    help="bench: rewrite only the benchmark tables (docs/results.md from its Benchmarks heading on, "
                         "the README's speed table) from reports/bench/bench.json, keeping the pose tables made from "
                         "reports measured elsewhere")
    args = ap.parse_args(argv)
    from silpose.app.rig.formats import formats_table
    from silpose.shared.atomic import write_text_atomic

    bench = args.reports / "bench" / "bench.json"
    if args.only == "bench":
        if not bench.is_file():
            raise SystemExit(f"results: {bench} not found: run `just bench` first")
        write_text_atomic(args.out, replace_benchmarks(args.out.read_text(encoding="utf-8"), bench))
        readme = replace_block(args.readme.read_text(encoding="utf-8"), "speed", speed_table(bench))
        write_text_atomic(args.readme, readme)
        print(f"wrote the benchmark tables of {args.out} and {args.readme}")
        return
    reports = load_reports(args.reports)
    write_text_atomic(args.out, results_markdown(reports, args.reports / "bench" / "bench.json"))
    readme = args.readme.read_text(encoding="utf-8")
    readme = replace_block(readme, "results", results_table(reports, README_ROWS))
    readme = replace_block(readme, "formats", formats_table())
    curve = curve_table(args.reports / "motions" / "learning_curve.json")
    readme = replace_block(readme, "curve", "\n".join(curve) if curve else
                           "(not measured: `python -m silpose.eval.learning_curve data/motions` writes it)")
    readme = replace_block(readme, "speed", speed_table(args.reports / "bench" / "bench.json"))
    write_text_atomic(args.readme, readme)
    print(f"wrote {args.out} and the tables of {args.readme}")


if __name__ == "__main__":
    main()
