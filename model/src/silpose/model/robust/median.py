"""The median along the last axis, ``np.median``'s result bit for bit at a fraction of its cost on many short rows.

Used by the robust weights (``silpose.model.robust.weights``) and the re-indexing fit (``silpose.model.robust.reindex``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["median_last"]


def median_last(values: np.ndarray) -> np.ndarray:
    """``np.median(values, axis=-1)`` (NaN where a row holds NaN), bit for bit: the same middle element(s) and the
    same mean of the two for even n, without np.median's generic reduction machinery (it dominated a single frame's
    reweighting pass). The rows are sorted, not partitioned: on many short rows numpy's sort is ~3x faster than its
    partition (4,096 rows of 200: 9.6 ms against 28 ms, with two kth values)."""
    v = np.asarray(values, dtype=np.float64)
    n = v.shape[-1]
    if n == 0:
        return np.full(v.shape[:-1], np.nan)
    k = n // 2
    ordered = np.sort(v, axis=-1)
    if n % 2:
        med = ordered[..., k]
    else:
        med = (ordered[..., k - 1] + ordered[..., k]) / 2.0
    return np.where(np.isnan(v).any(axis=-1), np.nan, med)
