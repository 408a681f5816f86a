"""silpose.shared.memory: freed heap memory goes back to the system."""

import sys

import numpy as np
import pytest

from silpose.shared.memory import release_freed_memory


def _rss_kb() -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc malloc_trim")
def test_freed_heap_blocks_are_returned():
    """Many 64 KB arrays (below glibc's mmap threshold, so from the heap) are freed, except the last one,
    which keeps the heap top from shrinking on its own: only malloc_trim gives the pages back."""
    blocks = [np.ones(8192) for _ in range(3000)]  # ~200 MB of heap
    keep = np.ones(8192)
    del blocks
    before = _rss_kb()
    assert release_freed_memory() is True
    after = _rss_kb()
    assert before - after > 100_000, (before, after)  # > 100 MB of the ~200 MB back
    del keep
