"""The largest all-True axis-aligned rectangle of a boolean grid (the maximal-rectangle algorithm).

Row by row, the heights of the columns of True cells form a histogram whose largest rectangle comes from
one pass with a stack, so the whole grid costs O(cells). Used for workspaces: the automatic workspace of
``silpose rig import`` (``silpose.app.rig.workspace``) and the part of a workspace every camera sees
(:meth:`silpose.shared.camera.Rig.seen_workspace`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["largest_histogram_rectangle", "largest_rectangle"]


def largest_histogram_rectangle(heights) -> tuple[int, int, int, int]:
    """(area, left, right, height) of the largest rectangle under a histogram (columns left..right inclusive).

    One pass with a stack of increasing heights; each bar's rectangle ends when a lower bar comes.
    """
    best = (0, 0, -1, 0)
    stack: list[tuple[int, int]] = []  # (start column, height)
    for i, h in enumerate(list(heights) + [0]):
        start = i
        while stack and stack[-1][1] >= h:
            s, sh = stack.pop()
            area = sh * (i - s)
            if area > best[0]:
                best = (area, s, i - 1, sh)
            start = s
        stack.append((start, h))
    return best


def largest_rectangle(mask: np.ndarray) -> tuple[int, int, int, int] | None:
    """(r0, r1, c0, c1), inclusive, of the largest-area all-True axis-aligned rectangle in ``mask``
    (ny, nx); None if ``mask`` has no True cell. Ties keep the first found (lowest bottom row)."""
    mask = np.asarray(mask, dtype=bool)
    heights = np.zeros(mask.shape[1], dtype=np.int64)
    best, rect = 0, None
    for r in range(mask.shape[0]):
        heights = np.where(mask[r], heights + 1, 0)
        area, c0, c1, h = largest_histogram_rectangle(heights.tolist())
        if area > best:
            best, rect = area, (r - h + 1, r, c0, c1)
    return rect
