"""Silhouette masks -> view contours, with the status of every (frame, camera) view.

A view is used when its mask has a largest blob of at least ``min_area`` pixels; its outer contour
is then extracted with :func:`silpose.shared.contours.extract_contour` at the model's ``n_points``
(the extraction the training data went through; the model normalises the pixel contours itself).
Any other view is a missing view, which the model marginalises. The statuses below are written to
``<out stem>.segmentation.json`` by ``silpose infer --frames``.
"""

from __future__ import annotations

import numpy as np

from silpose.shared.contours import EmptyMaskError, extract_contour

from .view_status import VIEW_EMPTY, VIEW_NO_VIDEO, VIEW_NOT_MODELLED, VIEW_OK, VIEW_TOO_SMALL

# the statuses of the frames pipeline, in the vocabulary every camera input shares (:mod:`.view_status`)
STATUS_OK = VIEW_OK
STATUS_NO_CAMERA = VIEW_NO_VIDEO
STATUS_EMPTY = VIEW_EMPTY
STATUS_SMALL = VIEW_TOO_SMALL
STATUS_NOT_MODELLED = VIEW_NOT_MODELLED
#: every status, in report order
STATUSES = (STATUS_OK, STATUS_NO_CAMERA, STATUS_EMPTY, STATUS_SMALL, STATUS_NOT_MODELLED)
#: default smallest usable blob, pixels (smaller blobs are noise, not a person)
DEFAULT_MIN_AREA = 50


def view_contour(mask: np.ndarray, n_points: int, min_area: int | None = None) -> tuple[np.ndarray | None, str, int]:
    """The contour of one view's silhouette, or why there is none.

    Args:
        mask: (H, W) bool silhouette.
        n_points: contour points (the model's n).
        min_area: smallest usable largest-blob area, px (None: any non-empty mask is used).
    Returns:
        (points (n_points, 2) px or None, status (``STATUS_OK``, ``STATUS_EMPTY`` or ``STATUS_SMALL``),
        area of the largest blob in px (0 when empty)).
    """
    try:
        ct = extract_contour(mask, n_points)
    except EmptyMaskError:
        return None, STATUS_EMPTY, 0
    if min_area is not None and ct.area < min_area:
        return None, STATUS_SMALL, ct.area
    return ct.points, STATUS_OK, ct.area
