"""Silhouette contours: extraction, arc-length resampling, normalisation, rasterisation (docs/conventions.md,
"Contours").

Conventions (binding for every package):

- Pixel coordinates: x right, y down, pixel centres at integer coordinates (OpenCV's).
- A contour is the OUTER boundary of the largest 8-connected foreground blob (holes ignored;
  equally large blobs: the one whose bounding box is topmost, then leftmost),
  traced through the centres of the blob's boundary pixels (``cv2.findContours``), so it lies
  about half a pixel inside the silhouette's geometric edge.
- Orientation: clockwise as seen on screen, i.e. a positive shoelace area
  ``A = 1/2 sum_i (x_i y_{i+1} - x_{i+1} y_i)`` in (x, y-down) coordinates.
- Start point: the upward vertical ray from the blob's area centroid (mean of its pixel
  centres) meets the outline; of all crossings of the vertical line ``x = c_x`` with the
  outline, the farthest up (smallest y) is taken, interpolated on the polyline. For a standing
  person that is the top of the head; unlike the topmost pixel it does not jump when an arm rises.
- Resampling: ``n_points`` points equally spaced in arc length along the closed polyline
  (linear interpolation), the first one at the start point.
- Normalisation (per view): translation by the centroid (mean of the n resampled points) and
  scale by THE scale measure ``s = sqrt(mean_i ||p_i - c||^2)`` (RMS distance from the centroid).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = [
    "EmptyMaskError",
    "Contour",
    "extract_contour",
    "extract_contours",
    "single_blob_contour",
    "normalise",
    "denormalise",
    "draw_contour",
    "signed_area",
    "outward_normals",
    "resample_closed",
    "N_POINTS",
]

N_POINTS = 200  #: default number of resampled contour points (the paper's n)


class EmptyMaskError(ValueError):
    """The mask has no foreground pixel, so there is no contour."""


@dataclass(frozen=True, eq=False)
class Contour:
    """The resampled outer contour of a silhouette's largest blob.

    Attributes:
        points: (n, 2) float32 pixel coordinates (x right, y down), clockwise on screen,
            starting at the top of the head (see the module docstring).
        area: pixels in the largest blob.
        length: perimeter in pixels of the raw (not resampled) boundary, ``cv2.arcLength``.
        n_blobs: number of 8-connected foreground components in the mask.
        touches_border: the largest blob has a pixel on the image border.
    """

    points: np.ndarray
    area: int
    length: float
    n_blobs: int
    touches_border: bool


def signed_area(points: np.ndarray) -> np.ndarray:
    """Shoelace area of closed polygons, positive when clockwise on screen (y down).

    ``A = 1/2 sum_i (x_i y_{i+1} - x_{i+1} y_i)``.

    Args:
        points: (..., n, 2) vertices in pixel coordinates.
    Returns:
        (...,) signed area in square pixels (float64).
    """
    p = np.asarray(points, dtype=np.float64)
    x, y = p[..., 0], p[..., 1]
    xn, yn = np.roll(x, -1, axis=-1), np.roll(y, -1, axis=-1)
    return 0.5 * np.sum(x * yn - xn * y, axis=-1)


def outward_normals(points: np.ndarray) -> np.ndarray:
    """Unit outward normals of closed contours.

    The tangent is the central difference ``t_i = p_{i+1} - p_{i-1}``; the normal
    ``(t_y, -t_x) / |t|`` points outward for a positive shoelace area and is flipped otherwise.

    Args:
        points: (..., n, 2) px.
    Returns:
        (..., n, 2) unit vectors (zero where the tangent vanishes).
    """
    p = np.asarray(points, dtype=np.float64)
    t = np.roll(p, -1, axis=-2) - np.roll(p, 1, axis=-2)
    nrm = np.stack([t[..., 1], -t[..., 0]], axis=-1)
    length = np.linalg.norm(nrm, axis=-1, keepdims=True)
    nrm = np.divide(nrm, length, out=np.zeros_like(nrm), where=length > 0)
    sign = np.where(signed_area(p) >= 0, 1.0, -1.0)
    return nrm * sign[..., None, None]


def _as_mask(mask: np.ndarray) -> np.ndarray:
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask must be 2-D (H, W), got shape {m.shape}")
    if m.size == 0:
        raise EmptyMaskError(f"mask of shape {m.shape} has no pixels")
    return (m != 0).astype(np.uint8)


def _start_on_polyline(poly: np.ndarray, cx: float) -> tuple[int, np.ndarray]:
    """Farthest-up crossing of the closed polyline with the vertical line ``x = cx``.

    Args:
        poly: (m, 2) float64 closed polyline vertices (the edge m-1 -> 0 is implied).
        cx: x of the blob's area centroid.
    Returns:
        (i, p): the crossing lies on edge i -> i+1 (mod m), at point p (2,).
        Without any crossing (degenerate outlines) the vertex nearest to the line, topmost
        among ties, is returned with its outgoing edge.
    """
    from .contour_kernels import start_on_polyline  # numba: imported when the first contour is traced

    i, p = start_on_polyline(np.ascontiguousarray(poly, dtype=np.float64), float(cx))
    return int(i), p


def resample_closed(poly: np.ndarray, start_edge: int, start: np.ndarray, n_points: int) -> np.ndarray:
    """Resample a closed polyline to ``n_points`` points equally spaced in arc length.

    Args:
        poly: (m, 2) vertices of the closed polyline (edge m-1 -> 0 implied).
        start_edge: index i of the edge i -> i+1 holding the start point.
        start: (2,) start point on that edge.
        n_points: number of output points.
    Returns:
        (n_points, 2) float64; point k at arc length ``k L / n_points`` from the start, in the
        polyline's direction (L = perimeter), linearly interpolated. A zero-length outline gives
        n copies of ``start``.
    """
    from .contour_kernels import resample_closed as compiled

    return compiled(np.ascontiguousarray(poly, dtype=np.float64), int(start_edge),
                    np.ascontiguousarray(start, dtype=np.float64), int(n_points))


def extract_contour(mask: np.ndarray, n_points: int = N_POINTS) -> Contour:
    """Outer contour of the largest 8-connected blob of a silhouette, resampled.

    Args:
        mask: (H, W) bool or integer array; non-zero is foreground.
        n_points: number of resampled points (>= 1).
    Returns:
        A :class:`Contour` whose ``points`` are (n_points, 2) float32 pixel coordinates,
        clockwise on screen (positive shoelace area in y-down coordinates), starting at the
        farthest-up crossing of the vertical line through the blob's area centroid with the
        outline (the top of the head).
        Degenerate blobs (one pixel, one-pixel-thin lines) give coinciding or back-and-forth
        points, never NaN.
    Raises:
        EmptyMaskError: the mask has no foreground pixel.
    """
    if int(n_points) < 1:
        raise ValueError(f"n_points must be >= 1, got {n_points}")
    m = _as_mask(mask)
    h, w = m.shape
    rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
    if rows.size == 0:
        raise EmptyMaskError(f"mask of shape {m.shape} has no foreground pixel")
    # Work inside the foreground's bounding box padded by one empty pixel (cropping does not
    # change connectivity, and the pad lets pixels on the image border be traced like any other).
    # sub-image (xs, ys) <-> image (xs + ox, ys + oy).
    r0, c0 = int(rows[0]), int(cols[0])
    ox, oy = c0 - 1, r0 - 1
    sub = np.zeros((int(rows[-1]) - r0 + 3, int(cols[-1]) - c0 + 3), np.uint8)
    sub[1:-1, 1:-1] = m[r0 : rows[-1] + 1, c0 : cols[-1] + 1]
    n_labels, labels, stats, centroids = cv2.connectedComponentsWithStats(sub, connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA]
    # Largest blob; ties (rare) go to the topmost, then leftmost bounding box, then centroid, so
    # the choice does not depend on OpenCV's label order (which changes with the crop).
    order = np.lexsort(
        (centroids[1:, 0], centroids[1:, 1], stats[1:, cv2.CC_STAT_LEFT], stats[1:, cv2.CC_STAT_TOP], -areas)
    )
    best = 1 + int(order[0])
    left, top = int(stats[best, cv2.CC_STAT_LEFT]), int(stats[best, cv2.CC_STAT_TOP])
    bw, bh = int(stats[best, cv2.CC_STAT_WIDTH]), int(stats[best, cv2.CC_STAT_HEIGHT])
    touches = bool(left + ox == 0 or top + oy == 0 or left + ox + bw == w or top + oy + bh == h)
    blob = (labels[top - 1 : top + bh + 1, left - 1 : left + bw + 1] == best).astype(np.uint8)
    pts, length = _trace(blob, (left - 1 + ox, top - 1 + oy), float(centroids[best, 0]) + ox, int(n_points))
    return Contour(
        points=pts.astype(np.float32),
        area=int(areas[best - 1]),
        length=length,
        n_blobs=int(n_labels - 1),
        touches_border=touches,
    )


def _trace(blob: np.ndarray, offset: tuple[int, int], cx: float, n_points: int,
           with_length: bool = True) -> tuple[np.ndarray, float]:
    """Resampled outer contour (n_points, 2) float64 in image px and raw perimeter (NaN unless ``with_length``) of
    the one 8-connected blob of ``blob`` ((h, w) uint8 {0, 1}, an empty pixel on every side); ``offset`` (x, y):
    image position of ``blob``'s pixel (0, 0); ``cx``: the blob's area centroid x in image px."""
    found, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    raw = max(found, key=len)  # one outer contour for an 8-connected blob
    length = float(cv2.arcLength(raw, closed=True)) if with_length else float("nan")
    from .contour_kernels import chain_outline  # numba: imported when the first contour is traced

    # cv2.contourArea(oriented=True) has the sign of the shoelace formula in (x, y-down): read backwards when
    # negative, to make it clockwise on screen; then started (_start_on_polyline) and resampled (resample_closed)
    reverse = bool(cv2.contourArea(raw, oriented=True) < 0)
    return chain_outline(raw.reshape(-1, 2), reverse, float(offset[0]), float(offset[1]), float(cx), n_points), length


def single_blob_contour(blob: np.ndarray, n_points: int = N_POINTS, offset: tuple[int, int] = (0, 0),
                        centroid_x: float | None = None, label: int | None = None) -> np.ndarray:
    """:func:`extract_contour`'s points for a mask known to hold ONE 8-connected blob (a labelled component
    cut out of a label image), without labelling it again: (n_points, 2) float32 px, ``offset`` (x, y) added
    (the image position of ``blob``'s pixel (0, 0)). The area centroid comes from ``cv2.moments`` (the mean
    of the blob's pixel centres, as the labelling's), or is ``centroid_x`` (x in ``blob``'s pixels, when the
    caller's labelling gave it). Raises EmptyMaskError on an empty mask.

    blob: (h, w) bool or uint8 {0, 1}; or, with ``label``, a label image (any integer type) whose pixels equal to
    ``label`` are the blob (a crop of a labelling, compared as it is copied: no mask of its own)."""
    if int(n_points) < 1:
        raise ValueError(f"n_points must be >= 1, got {n_points}")
    h, w = blob.shape
    padded = np.zeros((h + 2, w + 2), np.uint8)
    if label is None:
        padded[1:-1, 1:-1] = blob
    else:
        np.equal(blob, label, out=padded[1:-1, 1:-1].view(bool))
    if centroid_x is None:
        m = cv2.moments(padded, binaryImage=True)
        if m["m00"] <= 0:
            raise EmptyMaskError(f"mask of shape {blob.shape} has no foreground pixel")
        cx = m["m10"] / m["m00"] - 1 + offset[0]
    else:
        if not cv2.countNonZero(padded):
            raise EmptyMaskError(f"mask of shape {blob.shape} has no foreground pixel")
        cx = float(centroid_x) + offset[0]
    pts, _ = _trace(padded, (offset[0] - 1, offset[1] - 1), cx, int(n_points), with_length=False)
    return pts.astype(np.float32)


def extract_contours(masks: np.ndarray, n_points: int = N_POINTS) -> dict[str, np.ndarray]:
    """:func:`extract_contour` for a stack of masks (e.g. the K views of a sample).

    Args:
        masks: (K, H, W) bool or integer masks.
        n_points: number of resampled points per contour.
    Returns:
        dict with ``points`` (K, n_points, 2) float32, ``area`` (K,) int32, ``length`` (K,)
        float32, ``n_blobs`` (K,) int32, ``touches_border`` (K,) bool.
    Raises:
        EmptyMaskError: some mask is empty (the message names its index).
    """
    masks = np.asarray(masks)
    if masks.ndim != 3:
        raise ValueError(f"masks must have shape (K, H, W), got {masks.shape}")
    k = masks.shape[0]
    out = {
        "points": np.zeros((k, int(n_points), 2), np.float32),
        "area": np.zeros(k, np.int32),
        "length": np.zeros(k, np.float32),
        "n_blobs": np.zeros(k, np.int32),
        "touches_border": np.zeros(k, bool),
    }
    for j in range(k):
        try:
            c = extract_contour(masks[j], n_points)
        except EmptyMaskError as exc:
            raise EmptyMaskError(f"mask {j} of {k}: {exc}") from None
        out["points"][j] = c.points
        out["area"][j] = c.area
        out["length"][j] = c.length
        out["n_blobs"][j] = c.n_blobs
        out["touches_border"][j] = c.touches_border
    return out


def normalise(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Remove translation and scale from contours (per contour).

    ``c = mean_i p_i``, ``s = sqrt(mean_i ||p_i - c||^2)`` (RMS distance from the centroid,
    THE scale measure), ``q_i = (p_i - c) / s``. A degenerate contour (s == 0, all points
    equal) returns ``s = 0`` and ``q = 0`` (it is divided by 1 instead of 0), so
    :func:`denormalise` still gives the points back exactly; never NaN.

    Args:
        points: (..., n, 2) pixel coordinates.
    Returns:
        normalised (..., n, 2), centroid (..., 2), scale (...,); floating dtype of the input
        (float32 stays float32, integers become float64), computed in float64.
    """
    p = np.asarray(points)
    if p.ndim < 2 or p.shape[-1] != 2:
        raise ValueError(f"points must have shape (..., n, 2), got {p.shape}")
    dtype = p.dtype if np.issubdtype(p.dtype, np.floating) else np.float64
    p64 = p.astype(np.float64)
    c = p64.mean(axis=-2)
    d = p64 - c[..., None, :]
    s = np.sqrt(np.mean(np.sum(d * d, axis=-1), axis=-1))
    safe = np.where(s > 0, s, 1.0)
    q = d / safe[..., None, None]
    return q.astype(dtype), c.astype(dtype), s.astype(dtype)


def denormalise(normalised: np.ndarray, centroid: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Inverse of :func:`normalise`: ``p_i = s q_i + c``.

    Args:
        normalised: (..., n, 2); centroid: (..., 2) px; scale: (...,) px.
    Returns:
        (..., n, 2) pixel coordinates, float64 unless all inputs are float32.
    """
    q = np.asarray(normalised)
    c = np.asarray(centroid)
    s = np.asarray(scale)
    return q * s[..., None, None] + c[..., None, :]


_SHIFT = 4  # cv2 fixed-point bits: coordinates in 1/16 px


def draw_contour(points: np.ndarray, height: int, width: int) -> np.ndarray:
    """Rasterise a closed contour as a 1-pixel-wide 8-connected line.

    Uses ``cv2.polylines`` with sub-pixel precision (``shift`` = 4 bits, 1/16 px); the parts
    outside the image are clipped by OpenCV.

    Args:
        points: (n, 2) pixel coordinates (x right, y down, pixel centres at integers).
        height, width: image size in pixels.
    Returns:
        (height, width) bool image, True on the contour.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points must have shape (n, 2), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points contain NaN or infinity")
    img = np.zeros((int(height), int(width)), np.uint8)
    if len(p) == 0:
        return img.astype(bool)
    # Keep fixed-point coordinates far inside int32; lines that far out are clipped anyway.
    p = np.clip(p, -1e6, 1e6)
    fixed = np.round(p * (1 << _SHIFT)).astype(np.int32).reshape(-1, 1, 2)
    cv2.polylines(img, [fixed], isClosed=True, color=1, thickness=1, lineType=cv2.LINE_8, shift=_SHIFT)
    return img.astype(bool)
