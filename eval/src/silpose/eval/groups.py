"""Pose tables per activity group, for test sets posed from the motion library.

A dataset made with ``[motion] source = "library"`` lists its clips in the metadata
(``config.motion.clips``, each with a ``group``) and every row's ``gait.clip`` indexes that list.
:func:`sample_groups` reads the test split's groups; :func:`group_tables` repeats every experiment's
pose table (mean joint error, cm, root-relative, one row per condition) with one column per group
beside the overall one; :func:`write_group_report` writes them to ``groups.md``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_text_atomic
from silpose.shared.dataset import list_shards, load_split, read_metadata

from .tables import fmt

#: Condition columns of the results rows, in the order tables show them.
CONDITION_COLUMNS = ("method", "training", "trained_views", "input_views", "noise")


def sample_groups(dataset: str | Path) -> dict[int, str] | None:
    """``{sample_id: activity group}`` of ``dataset``'s test split, or None when its poses do not come
    from clips with groups (the procedural walk, BVH clips without groups)."""
    shards = list_shards(Path(dataset), "test")
    if not shards:
        return None
    clips = ((read_metadata(shards[0]).get("config") or {}).get("motion") or {}).get("clips") or []
    if not clips or not all("group" in c for c in clips):
        return None
    split = load_split(Path(dataset), "test", columns=["gait"])
    if "clip" not in split.gait:
        return None
    idx = np.asarray(split.gait["clip"], np.int64)
    return {int(s): str(clips[c]["group"]) if 0 <= c < len(clips) else "?" for s, c in zip(split.sample_id, idx)}


def group_tables(df, groups: dict[int, str]) -> str:
    """Markdown: per experiment, the mean pose error (cm) of every condition overall and per group."""
    if df is None or len(df) == 0 or "pose_cm" not in df:
        return ""
    g = df["sample_id"].map(lambda s: groups.get(int(s), "?"))
    names = sorted(set(g), key=lambda x: (x != "walk", x))
    counts = {n: int(sum(1 for v in groups.values() if v == n)) for n in names}
    out = ["Mean joint error (cm, root-relative) per activity group of the test clips; n = test samples per group: "
           + ", ".join(f"{n} {counts[n]}" for n in names) + ".\n"]
    for exp in sorted(df["experiment"].unique()):
        sub = df[df["experiment"] == exp]
        sg = g[df["experiment"] == exp]
        cols = [c for c in CONDITION_COLUMNS if c in sub and sub[c].nunique() > 1]
        head = ["condition", "all", *names]
        lines = [f"### {exp}\n", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        keys = sub[cols].astype(str).agg(" · ".join, axis=1) if cols else sub["experiment"]
        for key in dict.fromkeys(keys):
            m = (keys == key).to_numpy()
            cells = [key, fmt(float(np.nanmean(sub["pose_cm"].to_numpy()[m])))]
            for n in names:
                mm = m & (sg == n).to_numpy()
                cells.append(fmt(float(np.nanmean(sub["pose_cm"].to_numpy()[mm]))) if mm.any() else "–")
            lines.append("| " + " | ".join(cells) + " |")
        out += [*lines, ""]
    return "\n".join(out)


def write_group_report(df, groups: dict[int, str], out_dir: str | Path, title: str) -> Path:
    """Write ``groups.md`` (:func:`group_tables`) into ``out_dir``."""
    text = f"# {title}: pose error per activity group\n\n" + group_tables(df, groups) + "\n"
    return write_text_atomic(Path(out_dir) / "groups.md", text)


def group_headline(df, groups: dict[int, str]) -> dict:
    """The headline figures per activity group (JSON-friendly), for ``headline.json``'s ``by_group``.

    ``{group: {"n_test": samples, "pose_cm_by_n_views": {n: mean cm of E2 (posterior mean, standard noise)},
    "robust_cm_all_views": mean cm of E3's robust inference with every view under the standard noise,
    "baselines_cm_all_views": {method: mean cm of E4 with every view}}}``; groups without rows are left out.
    """
    if df is None or len(df) == 0 or "pose_cm" not in df:
        return {}
    g = df["sample_id"].map(lambda s: groups.get(int(s), "?")).to_numpy()
    pose = df["pose_cm"].to_numpy(float)
    exp = df["experiment"].to_numpy()
    n_views = df["n_input_views"].to_numpy() if "n_input_views" in df else np.zeros(len(df), int)
    method = df["method"].astype(str).to_numpy() if "method" in df else np.full(len(df), "mppca")
    noise = df["noise"].astype(str).to_numpy() if "noise" in df else np.full(len(df), "")
    all_views = int(n_views.max()) if len(n_views) else 0
    out: dict = {}
    for name in sorted(set(g), key=lambda x: (x != "walk", x)):
        mine = g == name
        entry: dict = {"n_test": int(sum(1 for v in groups.values() if v == name))}
        e2 = mine & (exp == "E2")
        entry["pose_cm_by_n_views"] = {int(n): float(pose[e2 & (n_views == n)].mean())
                                       for n in sorted(set(n_views[e2]), reverse=True)}
        robust = mine & (exp == "E3") & (method == "mppca robust") & (noise == "standard") & (n_views == all_views)
        if robust.any():
            entry["robust_cm_all_views"] = float(pose[robust].mean())
        e4 = mine & (exp == "E4") & (n_views == all_views)
        entry["baselines_cm_all_views"] = {m: float(pose[e4 & (method == m)].mean()) for m in sorted(set(method[e4]))}
        out[name] = entry
    return out
