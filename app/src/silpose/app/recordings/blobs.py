"""Connected components of one camera's mask: the candidate silhouettes a person can own.

:func:`find_blobs` labels the 8-connected components of a (H, W) mask (``cv2.connectedComponentsWithStats``)
and keeps, as usable blobs, those of at least ``min_area`` pixels; smaller ones (speckle left by a
lossy codec or a segmentation) are ignored. A blob touching the image border is flagged: its
outline is cut, so it is never used as a person's silhouette (docs/conventions.md, "Contours").
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from silpose.shared.contours import EmptyMaskError
from silpose.shared.contours import single_blob_contour


@dataclass(frozen=True, eq=False)
class Blobs:
    """The components of one mask.

    labels: (h, w) uint16 labels of the mask's foreground bounding box, whose top-left pixel is ``origin``
    (x, y) of the image: 0 = background, 1..L = components (:meth:`label_at` reads it in image pixels);
    usable: (L + 1,) bool, usable[label] (False for 0 and for components under ``min_area``); area:
    (L + 1,) int px; bbox: (L + 1, 4) int x, y, width, height in image pixels; centroid: (L + 1, 2) float
    px (area centroid); touches_border: (L + 1,) bool; empty: the mask had no foreground pixel at all.
    """

    labels: np.ndarray
    origin: tuple[int, int]
    usable: np.ndarray
    area: np.ndarray
    bbox: np.ndarray
    centroid: np.ndarray
    touches_border: np.ndarray
    empty: bool

    @property
    def n_usable(self) -> int:
        return int(self.usable.sum())

    def label_at(self, px: np.ndarray) -> np.ndarray:
        """Labels (...,) at integer image pixels ``px`` (..., 2) (x, y); 0 outside the labelled box."""
        x = np.asarray(px)[..., 0] - self.origin[0]
        y = np.asarray(px)[..., 1] - self.origin[1]
        h, w = self.labels.shape
        inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
        return np.where(inside, self.labels[np.clip(y, 0, h - 1), np.clip(x, 0, w - 1)], 0).astype(np.int64)


def find_blobs(mask: np.ndarray, min_area: int) -> Blobs:
    """Label ``mask`` ((H, W) uint8, non-zero = foreground) into :class:`Blobs`.

    Only the foreground's bounding box is labelled (``cv2.boundingRect``), with 16-bit labels: about 5x
    faster than labelling the whole 644x486 frame with 32-bit ones, for the same components.
    """
    h, w = mask.shape
    x0, y0, bw0, bh0 = cv2.boundingRect(mask)
    if bw0 == 0 or bh0 == 0:
        none = np.zeros(1)
        return Blobs(np.zeros((0, 0), np.uint16), (0, 0), np.zeros(1, bool), none.astype(int), np.zeros((1, 4), int),
                     np.zeros((1, 2)), np.zeros(1, bool), empty=True)
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(mask[y0 : y0 + bh0, x0 : x0 + bw0], connectivity=8,
                                                                   ltype=cv2.CV_16U)
    stats = stats.astype(np.int64)
    stats[:, 0] += x0
    stats[:, 1] += y0
    x, y, bw, bh, area = (stats[:, i] for i in range(5))
    touches = (x == 0) | (y == 0) | (x + bw == w) | (y + bh == h)
    usable = area >= int(min_area)
    usable[0] = False
    return Blobs(labels, (x0, y0), usable, area, stats[:, :4], centroids + (x0, y0), touches, empty=bool(n <= 1))


def blob_contour(blobs: Blobs, label: int, n_points: int) -> np.ndarray | None:
    """(n_points, 2) px outer contour of blob ``label`` (:func:`silpose.shared.contours.single_blob_contour`, which
    gives :func:`~silpose.shared.contours.extract_contour`'s points, on the blob alone cropped to its box), or
    None if the blob vanished."""
    x, y, bw, bh = (int(v) for v in blobs.bbox[label])
    ox, oy = blobs.origin
    crop = blobs.labels[y - oy : y - oy + bh, x - ox : x - ox + bw]
    try:
        # one component: no labelling again (extract_contour's points), its centroid the labelling's
        c = single_blob_contour(crop, n_points, centroid_x=float(blobs.centroid[label, 0]) - x, label=label)
    except EmptyMaskError:
        return None
    return c.astype(np.float64) + (x, y)
