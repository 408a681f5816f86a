"""A recording's run allocates numpy arrays in ordinary pages, not transparent huge pages.

numpy asks Linux for transparent huge pages (``madvise(MADV_HUGEPAGE)``) on every array of 4 MB or more. Where the
kernel's THP defragmentation is ``madvise`` (the default of common distributions, and of this project's machine),
the first touch of such an array may stop to compact memory into 2 MB pages. A recording's run allocates arrays of
that size by the hundred per second and uses each once: decoded full-HD frames (6.2 MB), a background's
statistics at the working size (11 MB float64 planes), per-frame work arrays. Measured on the project's 2-core
machine, the 1920x1080 colour benchmark recording (4 cameras, 150 steps), three alternating pairs: 90.6-107.8 CPU
ms per step in ordinary pages against 118.2-121.0 with numpy's default (13.3 / 16.1 / 13.9 against 12.3 / 12.1 /
12.4 time steps/s); the four backgrounds' statistics 0.23-0.29 s of system time against 0.66-1.15 s.

:func:`ordinary_pages` switches numpy's request off for the duration of a run and restores it afterwards; the
``NUMPY_MADVISE_HUGEPAGE`` environment variable (numpy's own switch, read when numpy is imported) wins when the
user has set it. It changes where the arrays' memory comes from, never a value.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Iterator

import numpy as np


def _switch():
    """numpy's setter of its huge-page request (``_set_madvise_hugepage(enabled) -> previous``), or None where this
    numpy has none (then nothing is changed)."""
    core = getattr(np, "core", None) or getattr(np, "_core", None)
    return getattr(getattr(core, "multiarray", None), "_set_madvise_hugepage", None)


@contextmanager
def ordinary_pages() -> Iterator[None]:
    """Within the block, numpy allocates without asking for transparent huge pages (module docstring), unless the
    user set ``NUMPY_MADVISE_HUGEPAGE``."""
    switch = _switch()
    if switch is None or os.environ.get("NUMPY_MADVISE_HUGEPAGE") is not None:
        yield
        return
    before = switch(False)
    try:
        yield
    finally:
        switch(before)
