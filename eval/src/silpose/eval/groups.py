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
