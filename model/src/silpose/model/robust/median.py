"""The median along the last axis, ``np.median``'s result bit for bit at a fraction of its cost on many short rows.

Used by the robust weights (``silpose.model.robust.weights``) and the re-indexing fit (``silpose.model.robust.reindex``).
"""

from __future__ import annotations

import numpy as np
from numpy.core._multiarray_umath import __cpu_features__

__all__ = ["median_last"]

# numpy < 2 sorts 64-bit rows with x86-simd-sort's AVX-512 quicksort where the CPU has it (AVX512_SKX), and there the
# sort beat np.partition ~3x on these rows (4,096 rows of 200: 9.6 ms against 28 ms, two kth values). Without AVX-512
# it is the other way round: on an AMD EPYC with AVX2 only, the sort took 29-31 ms and the partition 12.6 ms; 800 rows
# of 200: 6.0 against 2.4 ms; 16 rows: 52 against 17 us. Both give the exact order statistics, so the choice never
# changes a result. Robust inference of 2,000 benchmark frames (M 5, q 30, 2 threads) on that EPYC, three alternating
# runs: 1.18-1.31 s sorting, 1.14-1.16 s partitioning (one thread: 2.18 -> 1.76 s); single frames at M 200 within
# the noise (~9-12 ms either way).
SORT_IS_SIMD = bool(__cpu_features__.get("AVX512_SKX", False))


def median_last(values: np.ndarray) -> np.ndarray:
    """``np.median(values, axis=-1)`` (NaN where a row holds NaN), bit for bit: the same middle element(s) and the
    same mean of the two for even n, without np.median's generic reduction machinery (it dominated a single frame's
    reweighting pass). The middle elements come from a sort of the rows where numpy's sort is vectorised (AVX-512),
    else from a partition at them (``SORT_IS_SIMD``)."""
    v = np.asarray(values, dtype=np.float64)
    n = v.shape[-1]
    if n == 0:
        return np.full(v.shape[:-1], np.nan)
    k = n // 2
    if SORT_IS_SIMD:
        ordered = np.sort(v, axis=-1)
    else:
        ordered = np.partition(v, k if n % 2 else (k - 1, k), axis=-1)
    if n % 2:
        med = ordered[..., k]
    else:
        med = (ordered[..., k - 1] + ordered[..., k]) / 2.0
    return np.where(np.isnan(v).any(axis=-1), np.nan, med)
