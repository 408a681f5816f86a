"""Silhouette masks -> view contours, with the status of every (frame, camera) view.

A view is used when its mask has a largest blob of at least ``min_area`` pixels; its outer contour
is then extracted with :func:`silpose.shared.contours.extract_contour` at the model's ``n_points``
(the extraction the training data went through; the model normalises the pixel contours itself).
Any other view is a missing view, which the model marginalises; its status is a word of
:mod:`.view_status` (``empty mask``, ``too small``). Used for silhouette images (``silpose infer INPUT``,
:mod:`.inputs.silhouettes`); camera inputs take their blobs from :mod:`.recordings.blobs`.
"""

from __future__ import annotations

import numpy as np

from silpose.shared.contours import EmptyMaskError, extract_contour

from .view_status import VIEW_EMPTY, VIEW_OK, VIEW_TOO_SMALL


def view_contour(mask: np.ndarray, n_points: int, min_area: int | None = None) -> tuple[np.ndarray | None, str, int]:
    """The contour of one view's silhouette, or why there is none.

    Args:
        mask: (H, W) bool silhouette.
        n_points: contour points (the model's n).
        min_area: smallest usable largest-blob area, px (None: any non-empty mask is used).
    Returns:
        (points (n_points, 2) px or None, status (``VIEW_OK``, ``VIEW_EMPTY`` or ``VIEW_TOO_SMALL``),
        area of the largest blob in px (0 when empty)).
    """
    try:
        ct = extract_contour(mask, n_points)
    except EmptyMaskError:
        return None, VIEW_EMPTY, 0
    if min_area is not None and ct.area < min_area:
        return None, VIEW_TOO_SMALL, ct.area
    return ct.points, VIEW_OK, ct.area
