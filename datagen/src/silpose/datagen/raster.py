"""Silhouette rasteriser: project a triangle mesh with a calibrated camera and fill it. No bpy.

Used by the ``raster`` renderer on Blender's evaluated (posed) mesh. The sampling rule is the
one of a GPU rasteriser without anti-aliasing (what Workbench does): a pixel is foreground when
its CENTRE lies inside (or on the edge of) a projected triangle; pixel centres are at integer
coordinates (OpenCV's convention). The silhouette is the union over all triangles, front or
back facing.

Three fillers are provided:

- :func:`fill_triangles_scanline` (default): the same rule per (triangle, pixel row) span,
  accumulated in a difference image; several times faster than per-pixel tests.
- :func:`fill_triangles_exact`: vectorised numpy edge functions over each triangle's
  bounding box of pixel centres. Exact pixel-centre sampling.
- :func:`fill_triangles_cv2`: ``cv2.fillPoly`` with 8 bits of sub-pixel precision, one call
  for all triangles. OpenCV also fills pixels its outline *touches*, so it grows silhouettes by
  up to half a pixel: measured IoU 0.86-0.91 against the pixel-centre rule on the default rig
  (20 bodies x 4 views), far from the >= 0.99 agreement with Blender's render that the exact
  rule reaches. Kept as a reference, not used.
"""

from __future__ import annotations

import cv2
import numpy as np

from silpose.shared.camera import Camera

_SHIFT = 8  # cv2 sub-pixel bits


def project_triangles(vertices: np.ndarray, triangles: np.ndarray, camera: Camera) -> np.ndarray:
    """Project mesh triangles to pixels.

    Args:
        vertices: (V, 3) world coordinates, metres.
        triangles: (T, 3) integer vertex indices.
        camera: the calibrated camera (``Camera.project``, distortion included).
    Returns:
        (T, 3, 2) float64 pixel coordinates.
    Raises:
        ValueError: some vertex is at or behind the camera plane.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    depth = camera.to_camera(vertices)[:, 2]
    if np.any(depth <= 1e-6):
        raise ValueError(f"camera {camera.name!r}: {int(np.sum(depth <= 1e-6))} mesh vertices behind the camera")
    uv = camera.project(vertices)
    return uv[np.asarray(triangles)]


def fill_triangles_exact(tri_px: np.ndarray, height: int, width: int) -> np.ndarray:
    """Pixel-centre coverage of the union of triangles.

    A pixel (x, y) (integer centre) is set when for a triangle (a, b, c) the three edge
    functions ``E_ab(p) = (b - a) x (p - a)`` (2-D cross product) all have the same sign or
    are zero (Pineda, "A parallel algorithm for polygon rasterization", SIGGRAPH 1988).

    Args:
        tri_px: (T, 3, 2) pixel coordinates (x right, y down).
        height, width: image size.
    Returns:
        (height, width) uint8 mask in {0, 1}.
    """
    mask = np.zeros((height, width), np.uint8)
    tri = np.asarray(tri_px, dtype=np.float64)
    if tri.size == 0:
        return mask
    lo = np.ceil(tri.min(axis=1)).astype(np.int64)  # (T, 2) first pixel centre >= min
    hi = np.floor(tri.max(axis=1)).astype(np.int64)
    lo = np.maximum(lo, 0)
    hi = np.minimum(hi, (width - 1, height - 1))
    nx = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0)
    ny = np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    n = nx * ny
    keep = n > 0
    if not np.any(keep):
        return mask
    tri, lo, nx, n = tri[keep], lo[keep], nx[keep], n[keep]
    idx = np.repeat(np.arange(len(n)), n)
    start = np.repeat(np.cumsum(n) - n, n)
    local = np.arange(idx.size) - start
    nxi = nx[idx]
    px = lo[idx, 0] + local % nxi
    py = lo[idx, 1] + local // nxi
    t = tri[idx]  # (P, 3, 2)
    fx, fy = px.astype(np.float64), py.astype(np.float64)
    pos = np.ones(idx.size, bool)
    neg = np.ones(idx.size, bool)
    for i in range(3):
        a, b = t[:, i], t[:, (i + 1) % 3]
        e = (b[:, 0] - a[:, 0]) * (fy - a[:, 1]) - (b[:, 1] - a[:, 1]) * (fx - a[:, 0])
        pos &= e >= 0
        neg &= e <= 0
    inside = pos | neg
    mask[py[inside], px[inside]] = 1
    return mask


def fill_triangles_scanline(tri_px: np.ndarray, height: int, width: int) -> np.ndarray:
    """Pixel-centre coverage of the union of triangles, by scanline spans (the fast default).

    Same rule as :func:`fill_triangles_exact` (pixel centres inside or on a triangle), computed
    per (triangle, pixel row) instead of per pixel: the row ``y`` (integer) cuts the triangle's
    edges at ``x = x_a + (y - y_a) (x_b - x_a) / (y_b - y_a)``; the span ``[min x, max x]``
    covers the centres ``ceil(min x) .. floor(max x)``. Spans are accumulated as +1/-1 in a
    difference image (``np.bincount``) and integrated with a cumulative sum along rows.

    Args:
        tri_px: (T, 3, 2) pixel coordinates (x right, y down), or (K, T, 3, 2) for K images
            of the same size at once (one image per leading index).
        height, width: image size.
    Returns:
        (height, width) uint8 mask in {0, 1}, or (K, height, width) for a (K, T, 3, 2) input.
    """
    tri = np.asarray(tri_px, dtype=np.float64)
    single = tri.ndim == 3
    if single:
        tri = tri[None]
    k_img, n_tri = tri.shape[:2]
    out = np.zeros((k_img, height, width), np.uint8)
    if tri.size == 0:
        return out[0] if single else out
    tri = tri.reshape(-1, 3, 2)
    view = np.repeat(np.arange(k_img), n_tri)
    ys = tri[:, :, 1]
    y0 = np.maximum(np.ceil(ys.min(axis=1)), 0).astype(np.int64)
    y1 = np.minimum(np.floor(ys.max(axis=1)), height - 1).astype(np.int64)
    nrows = np.maximum(y1 - y0 + 1, 0)
    idx = np.repeat(np.arange(len(tri)), nrows)
    if idx.size == 0:
        return out[0] if single else out
    row = y0[idx] + (np.arange(idx.size) - np.repeat(np.cumsum(nrows) - nrows, nrows))
    y = row.astype(np.float64)
    t = tri[idx]  # (P, 3, 2)
    xl = np.full(idx.size, np.inf)
    xr = np.full(idx.size, -np.inf)
    for i in range(3):
        a, b = t[:, i], t[:, (i + 1) % 3]
        dy = b[:, 1] - a[:, 1]
        ok = (dy != 0) & (y >= np.minimum(a[:, 1], b[:, 1])) & (y <= np.maximum(a[:, 1], b[:, 1]))
        x = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / np.where(ok, dy, 1.0)
        xl = np.where(ok, np.minimum(xl, x), xl)
        xr = np.where(ok, np.maximum(xr, x), xr)
    xs = np.maximum(np.ceil(xl), 0)
    xe = np.minimum(np.floor(xr), width - 1)
    ok = xs <= xe
    if not np.any(ok):
        return out[0] if single else out
    row, vk = row[ok], view[idx[ok]]
    xs, xe = xs[ok].astype(np.int64), xe[ok].astype(np.int64)
    # one difference buffer holding, per image, only its touched rows x columns (+1 column for
    # the closing -1). Every span adds +1 and -1 within its own row, so a single cumulative sum
    # over the flat buffer restarts at 0 at every row.
    r0 = np.full(k_img, height, np.int64)
    r1 = np.zeros(k_img, np.int64)
    c0 = np.full(k_img, width, np.int64)
    c1 = np.zeros(k_img, np.int64)
    np.minimum.at(r0, vk, row)
    np.maximum.at(r1, vk, row + 1)
    np.minimum.at(c0, vk, xs)
    np.maximum.at(c1, vk, xe + 2)
    nr, w = np.maximum(r1 - r0, 0), np.maximum(c1 - c0, 0)
    size = nr * w
    base = np.cumsum(size) - size
    start = base[vk] + (row - r0[vk]) * w[vk] - c0[vk]
    total = int(size.sum())
    cover = np.cumsum(np.bincount(start + xs, minlength=total) - np.bincount(start + xe + 1, minlength=total)) > 0
    for k in range(k_img):
        if size[k]:
            block = cover[base[k] : base[k] + size[k]].reshape(nr[k], w[k])
            out[k, r0[k] : r1[k], c0[k] : c1[k] - 1] = block[:, :-1]
    return out[0] if single else out


def fill_triangles_cv2(tri_px: np.ndarray, height: int, width: int) -> np.ndarray:
    """``cv2.fillPoly`` of every triangle with sub-pixel precision (see the module docstring).

    Returns:
        (height, width) uint8 mask in {0, 1}.
    """
    mask = np.zeros((height, width), np.uint8)
    pts = np.round(np.asarray(tri_px, dtype=np.float64) * (1 << _SHIFT)).astype(np.int32)
    for tri in pts:  # one polygon per call: fillPoly of several polygons XORs overlaps
        cv2.fillConvexPoly(mask, tri, 1, lineType=cv2.LINE_8, shift=_SHIFT)
    return mask


_FILLERS = ("scanline", "exact", "cv2")


def rasterize(vertices: np.ndarray, triangles: np.ndarray, camera: Camera, method: str = "scanline") -> np.ndarray:
    """Silhouette of a mesh in one camera.

    Args:
        vertices: (V, 3) world metres; triangles: (T, 3) vertex indices.
        camera: calibrated camera.
        method: ``"scanline"`` (pixel-centre rule, default), ``"exact"`` (same rule, per-pixel
            edge functions; the reference) or ``"cv2"``.
    Returns:
        (H, W) uint8 mask in {0, 1}.
    """
    tri_px = project_triangles(vertices, triangles, camera)
    if method == "scanline":
        return fill_triangles_scanline(tri_px, camera.height, camera.width)
    if method == "exact":
        return fill_triangles_exact(tri_px, camera.height, camera.width)
    if method == "cv2":
        return fill_triangles_cv2(tri_px, camera.height, camera.width)
    raise ValueError(f"method must be one of {_FILLERS}, got {method!r}")


def project_vertices(vertices: np.ndarray, cameras, min_depth: float = 1e-6) -> np.ndarray | None:
    """Project mesh vertices into every camera.

    Args:
        vertices: (V, 3) world metres.
        cameras: a Rig or a list of cameras.
        min_depth: vertices closer than this (metres, camera z) count as behind the camera.
    Returns:
        (K, V, 2) float64 pixels, or None when some vertex is behind some camera or beyond its lens
        model's domain (``Camera.max_radius``).
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    out = []
    for cam in cameras:
        if np.any(cam.to_camera(vertices)[:, 2] <= min_depth):
            return None
        uv = cam.project(vertices)
        if not np.all(np.isfinite(uv)):
            return None
        out.append(uv)
    return np.stack(out)


def rasterize_projected(uv: np.ndarray, triangles: np.ndarray, height: int, width: int) -> np.ndarray:
    """(K, H, W) uint8 silhouettes from projected vertices ``uv`` (K, V, 2) and (T, 3) triangles."""
    uv = np.asarray(uv, dtype=np.float64)
    return fill_triangles_scanline(uv[:, np.asarray(triangles)], height, width)


def rasterize_rig(vertices: np.ndarray, triangles: np.ndarray, cameras, method: str = "scanline") -> np.ndarray:
    """(K, H, W) uint8 silhouettes of one mesh in every camera of ``cameras`` (a Rig or list).

    With the scanline filler and cameras of one image size, all views are filled in one
    vectorised call.
    """
    cameras = list(cameras)
    sizes = {(c.height, c.width) for c in cameras}
    if method == "scanline" and len(sizes) == 1:
        H, W = sizes.pop()
        tri_px = np.stack([project_triangles(vertices, triangles, c) for c in cameras])
        return fill_triangles_scanline(tri_px, H, W)
    return np.stack([rasterize(vertices, triangles, c, method) for c in cameras])
