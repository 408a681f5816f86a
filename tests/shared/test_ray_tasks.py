"""The Ray task-loop helpers (silpose.shared.ray_tasks), with a stand-in for the ray module."""

from __future__ import annotations

from silpose.shared.ray_tasks import cancel_pending, task_failure_message


class _FakeRay:
    def __init__(self, gone):
        self.gone, self.cancelled = set(gone), []

    def cancel(self, ref, force=False):
        assert force is True
        if ref in self.gone:
            raise ValueError(f"{ref} already finished")
        self.cancelled.append(ref)


def test_cancel_pending_cancels_every_ref_and_skips_finished_ones():
    ray = _FakeRay(gone={"b"})
    cancel_pending(ray, {"a": 1, "b": 2, "c": 3})
    assert ray.cancelled == ["a", "c"]


def test_task_failure_message_is_the_last_line_or_the_type():
    assert task_failure_message(RuntimeError("Traceback ...\n  File x\nValueError: bad shard")) == "ValueError: bad shard"
    assert task_failure_message(KeyError()) == "KeyError"
