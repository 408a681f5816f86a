"""Summary statistics and Markdown table formatting shared by the evaluation reports.

Every report table gives, per condition, the mean, median and quartiles (Q1, Q3) of the finite
values; missing numbers print as an en dash. Used by :mod:`silpose.eval.report` (``summary.md``),
:mod:`silpose.eval.frames_eval` (``frames.md``) and :mod:`silpose.eval.plots`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["QUARTILE_HEADERS", "stats", "fmt", "fmt_stats", "markdown_table", "select"]

#: Column headers of :func:`fmt_stats`'s four cells, in order.
QUARTILE_HEADERS = ("mean", "median", "Q1", "Q3")


def stats(values) -> dict:
    """n, mean, median, q1, q3 of the finite values (NaN when none).

    Args:
        values: array-like of any shape; NaN and infinities are left out.
    Returns:
        ``{"n": int, "mean", "median", "q1", "q3": float}`` (quartiles by linear interpolation,
        ``numpy.percentile``'s default).
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return {"n": 0, "mean": np.nan, "median": np.nan, "q1": np.nan, "q3": np.nan}
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return {"n": int(len(v)), "mean": float(v.mean()), "median": float(med), "q1": float(q1), "q3": float(q3)}


def fmt(x, digits: int = 2) -> str:
    """``x`` with ``digits`` decimals; "–" for None, NaN or infinity."""
    return "–" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def fmt_stats(s: dict) -> str:
    """Four Markdown cells ``mean | median | Q1 | Q3`` of a :func:`stats` dict, 2 decimals."""
    return f"{fmt(s['mean'])} | {fmt(s['median'])} | {fmt(s['q1'])} | {fmt(s['q3'])}"


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    """A GitHub-flavoured Markdown table (a row's cell may itself hold ``" | "``-joined cells)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def select(df, **eq):
    """Rows of the DataFrame ``df`` whose columns equal the given values (``select(df, experiment="E2")``)."""
    m = np.ones(len(df), bool)
    for k, v in eq.items():
        m &= (df[k] == v).to_numpy()
    return df[m]
