"""StepAhead (silpose.app.recordings.lookahead): each camera's steps in order, the same results as the plain
loop, nothing read beyond the last step asked for; and the run's setup / finish timings."""

from __future__ import annotations

import random
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from silpose.app.recordings.lookahead import StepAhead
from silpose.app.recordings.pipeline import RecordingSummary


class _Counter:
    """A camera whose step k returns (name, k), after a random pause (threads finish out of order)."""

    def __init__(self, name: str, seed: int):
        self.name, self.k, self.rng = name, 0, random.Random(seed)
        self.busy = threading.Lock()
        self.overlapped = False  # two of its steps ran at once

    def step(self):
        if not self.busy.acquire(blocking=False):
            self.overlapped = True
            self.busy.acquire()
        try:
            time.sleep(self.rng.random() * 0.002)
            self.k += 1
            return (self.name, self.k - 1)
        finally:
            self.busy.release()


def test_steps_ahead_come_in_order_and_stop_at_the_last():
    cams = [_Counter(f"c{i}", i) for i in range(4)]
    with ThreadPoolExecutor(max_workers=3) as pool:
        ahead = StepAhead([c.step for c in cams], pool, ahead=True)
        got = [ahead.next(more=t + 1 < 12) for t in range(12)]
        ahead.drain()
    assert got == [[(f"c{i}", t) for i in range(4)] for t in range(12)]
    assert [c.k for c in cams] == [12] * 4  # no 13th frame read
    assert not any(c.overlapped for c in cams)


def test_plain_and_pooled_steps_agree():
    plain = [_Counter(f"c{i}", i) for i in range(3)]
    pooled = [_Counter(f"c{i}", i) for i in range(3)]
    a = StepAhead([c.step for c in plain], None, ahead=True)  # no pool: nothing ahead
    with ThreadPoolExecutor(max_workers=2) as pool:
        b = StepAhead([c.step for c in pooled], pool, ahead=True)
        ra = [a.next() for _ in range(5)]
        rb = [b.next() for _ in range(5)]
        b.drain()
    assert ra == rb
    assert [c.k for c in plain] == [5] * 3 and [c.k for c in pooled] == [6] * 3  # the pooled ones one step ahead


def test_steady_rate_leaves_out_setup_and_finish(tmp_path):
    s = RecordingSummary(tmp_path, [], 50, 1, {}, [0], {}, {"cameras": 0.3, "setup": 0.5, "total": 2.0, "finish": 0.5})
    assert s.steps_per_second == 25.0 and s.steady_steps_per_second == 50.0
