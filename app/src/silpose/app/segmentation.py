"""Camera frames -> silhouette masks: the paper's background subtraction (:mod:`silpose.segment`), per camera.

One :class:`silpose.segment.BackgroundModel` per camera is fitted on that camera's empty-scene
frames, then segments its frames chunk by chunk. Segmentation errors (a bad parameter, a frame
that does not match its background) become :class:`~silpose.app.errors.FramesInputError`.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from silpose.segment import BackgroundModel, SegmentError

from .errors import FramesInputError
from .inputs.frames_folder import FramesFolder


def fit_backgrounds(folder: FramesFolder, cameras: Sequence[str], params: dict | None = None) -> dict[str, BackgroundModel]:
    """{camera: BackgroundModel fitted on its background frames} for ``cameras`` of ``folder``.

    params: keyword arguments of :class:`silpose.segment.BackgroundModel` (None = the defaults).
    """
    try:
        return {c: BackgroundModel(**(params or {})).fit(folder.background(c)) for c in cameras}
    except SegmentError as exc:
        raise FramesInputError(str(exc)) from None


def segment_chunk(models: dict[str, BackgroundModel], images: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """{camera: (n, H, W) bool masks} of one chunk of frames {camera: (n, H, W, 3) uint8 BGR}, for the
    cameras of ``models``."""
    try:
        return {c: m.segment_batch(images[c]) for c, m in models.items()}
    except SegmentError as exc:
        raise FramesInputError(str(exc)) from None
