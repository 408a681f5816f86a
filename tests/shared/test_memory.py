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


def test_peak_rss_covers_a_block_touched_and_freed():
    """After a 300 MB block is touched and freed, the peak is still at least the resident size the process had
    while it held the block (psutil's figure, an independent reader); the current size has fallen by then."""
    import psutil

    from silpose.shared.memory import peak_rss_bytes

    before = peak_rss_bytes()
    block = np.ones(300 * 2**20 // 8)  # touched: resident
    during = psutil.Process().memory_info().rss
    del block
    after = peak_rss_bytes()
    assert after >= during - 2**20 and after >= before
    assert psutil.Process().memory_info().rss < during - 200 * 2**20  # what a current-size reader would give


def test_peak_rss_is_this_process_own():
    """A child started by this process reports its own peak, not the parent's (``ru_maxrss`` would carry the
    parent's over ``exec``)."""
    import subprocess

    from silpose.shared.memory import peak_rss_bytes

    ballast = np.ones(60 * 2**20, np.uint8)  # 60 MiB in this process ...
    assert peak_rss_bytes() > ballast.size
    code = "from silpose.shared.memory import peak_rss_bytes; print(peak_rss_bytes())"
    child = int(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)
    assert child < ballast.size  # ... not in a child it starts
