"""The cameras' next time step started while the run's thread is busy with the current one.

:class:`StepAhead` gives the pipeline each step's per-camera results (``silpose infer --videos``,
:mod:`.pipeline`). With ``ahead``, as soon as a step's results are handed over, every camera's next step is
submitted to the thread pool, so its decoding, binarising and labelling (OpenCV, which releases the GIL) run
while the run's thread finds people on the floor and judges their views (numpy and Python) -- stages that
otherwise took turns. Each camera's steps still run one after the other (the next is submitted only once the
current one has finished), so every camera reads its frames in order and the results are those of the plain
loop, step for step.

Between two steps the run's thread may change what a camera's next step computes: with colour videos, static
clutter becomes background (:meth:`~.camera_step.CameraStep.settle`). The pipeline then first waits for that camera's
step started ahead (:meth:`StepAhead.wait`: the background model never changes under a segmentation) and, when it
is handed over, segments its frame again against the new background (:meth:`~.camera_step.CameraStep.resegment`) --
rare (clutter that stays two seconds), and what the plain loop would have computed. ``more`` tells
:meth:`StepAhead.next` whether another step will be asked for, so no frame is read beyond the run's last step
(``--max-steps``); the cameras' tallies for their end-of-run diagnoses are taken as the steps are handed over.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from typing import Callable, Sequence


class StepAhead:
    """Per-camera steps ``steps`` (callables, one per camera, each returning that camera's result of the next
    time step) run in ``pool`` (None: in the calling thread, nothing ahead); ``ahead``: start the next step
    before the caller asks for it (module docstring)."""

    def __init__(self, steps: Sequence[Callable[[], object]], pool: ThreadPoolExecutor | None, ahead: bool):
        self.steps, self.pool = list(steps), pool
        self.ahead = bool(ahead) and pool is not None
        self._pending: list[Future] | None = None

    def _submit(self) -> list[Future]:
        return [self.pool.submit(s) for s in self.steps]

    def next(self, more: bool = True) -> list:
        """The cameras' results of the next step, in camera order; ``more``: another step will follow (then,
        with ``ahead``, it is started before returning)."""
        if self.pool is None:
            return [s() for s in self.steps]
        futures, self._pending = self._pending or self._submit(), None
        out = [f.result() for f in futures]
        if self.ahead and more:
            self._pending = self._submit()
        return out

    def wait(self, k: int) -> None:
        """Wait until camera ``k``'s step started ahead (if any) has finished (its error, if any, comes with
        :meth:`next`)."""
        if self._pending:
            self._pending[k].exception()

    def drain(self) -> None:
        """Wait for a step started ahead and never asked for (a run that stopped early); its errors are dropped."""
        for f in self._pending or []:
            f.exception()
        self._pending = None
