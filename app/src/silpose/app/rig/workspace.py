"""The automatic workspace: the largest floor rectangle where a tall person is fully visible.

In silpose's frame (z up, metres, floor z = 0) the floor is cut into square cells of side ``step``.
A person standing anywhere in a cell is modelled as the box ``[x +- h, y +- h] x [0, H]`` with
``h = footprint / 2 + step / 2`` (the footprint around the cell centre, grown by half a cell so the
box covers every position inside the cell) and ``H`` the tallest person's height. The box is
convex, so it is fully in view of a camera when its eight corners are in front of the camera
(depth > :data:`MIN_DEPTH_M`) and project inside the image (with the camera's distortion; and,
against the distortion polynomial folding far points back into the image, their undistorted
normalised coordinates lie within the image's own, :func:`normalised_bounds`). A cell counts for a
camera when the box is fully visible and the person, at the cell centre, is at least
``min_person_px`` pixels tall in it (this bounds the region far from the cameras). A cell is
*visible* when at least ``min_views`` cameras count it.

The workspace is the largest-area axis-aligned rectangle of visible cells, found with the classic
maximal-rectangle algorithm: row by row, the heights of the columns of visible cells form a
histogram whose largest rectangle comes from one pass with a stack
(:func:`silpose.shared.rectangles.largest_rectangle`, O(cells); re-exported here).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from silpose.shared.camera import Camera
from silpose.shared.rectangles import largest_histogram_rectangle, largest_rectangle
from silpose.shared.rig_frame import PERSON_HEIGHT_M, Workspace

__all__ = ["VisibilityGrid", "visibility_grid", "largest_rectangle", "largest_histogram_rectangle",
           "auto_workspace", "normalised_bounds", "MIN_DEPTH_M", "MIN_PERSON_FRACTION", "MAX_CELLS_PER_SIDE",
           "DEFAULT_FOOTPRINT_M", "project_fast"]

#: Default side (metres) of the person's square footprint. 0: the person is the vertical segment from
#: the floor to ``PERSON_HEIGHT_M`` at the walker's (pelvis) position, the criterion of
#: ``Rig.check_sees_workspace`` and of the built-in rig's 3 m x 3 m square (a 0.5 m footprint shrinks
#: that square to 2.65 m x 2.90 m). Limbs swinging outside the image are rejected by the generator,
#: which redraws the sample; ``--footprint`` keeps a margin instead.
DEFAULT_FOOTPRINT_M = 0.0
#: Nearest depth (metres) at which a box corner still counts as in front of a camera.
MIN_DEPTH_M = 0.1
#: Default smallest image height of the tallest person, as a fraction of the image height.
MIN_PERSON_FRACTION = 0.25
#: Floor cells per side at most (the step grows for very large regions).
MAX_CELLS_PER_SIDE = 400


@dataclass(frozen=True, eq=False)
class VisibilityGrid:
    """Per-cell visibility of a person on the floor.

    Attributes:
        xs, ys: (nx,), (ny,) cell centres, metres.
        step: cell side, metres.
        per_camera: (K, ny, nx) bool, the person is fully visible (and large enough) in camera k.
        min_views: cameras required per cell.
    """

    xs: np.ndarray
    ys: np.ndarray
    step: float
    per_camera: np.ndarray
    min_views: int

    @property
    def counts(self) -> np.ndarray:
        """(ny, nx) int: cameras that see the person in each cell."""
        return self.per_camera.sum(axis=0)

    @property
    def visible(self) -> np.ndarray:
        """(ny, nx) bool: cells seen by at least ``min_views`` cameras."""
        return self.counts >= self.min_views

    def rectangle_workspace(self, rect: tuple[int, int, int, int]) -> Workspace:
        """The floor rectangle covering cells rows r0..r1, columns c0..c1 (inclusive)."""
        r0, r1, c0, c1 = rect
        x0, x1 = self.xs[c0] - self.step / 2, self.xs[c1] + self.step / 2
        y0, y1 = self.ys[r0] - self.step / 2, self.ys[r1] + self.step / 2
        # whole cells: the size is (cells x step), free of the float sums' 1e-15 m (rig.json shows 3.0, not 2.9999999999999893)
        size = [round((c1 - c0 + 1) * self.step, 9), round((r1 - r0 + 1) * self.step, 9)]
        return Workspace([round((x0 + x1) / 2, 9), round((y0 + y1) / 2, 9)], size)


def normalised_bounds(cam: Camera, samples: int = 16) -> np.ndarray:
    """(2, 2) [[x_min, y_min], [x_max, y_max]] of the undistorted normalised coordinates of the image
    border (``Camera.normalised``), grown by 10 %: points beyond cannot be in the image."""
    W, H = cam.width, cam.height
    s = np.linspace(0.0, 1.0, samples)
    border = np.concatenate([np.stack([s * (W - 1), np.zeros_like(s)], 1), np.stack([s * (W - 1), np.full_like(s, H - 1)], 1),
                             np.stack([np.zeros_like(s), s * (H - 1)], 1), np.stack([np.full_like(s, W - 1), s * (H - 1)], 1)])
    n = cam.normalised(border)
    lo, hi = n.min(axis=0), n.max(axis=0)
    pad = 0.1 * (hi - lo)
    return np.stack([lo - pad, hi + pad])


def project_fast(cam: Camera, points: np.ndarray) -> np.ndarray:
    """``cam.project(points)`` ((N, 3) metres -> (N, 2) px) without ``cv2.projectPoints``' Jacobians.

    OpenCV's distortion model written out for 4, 5, 8 and 12 coefficients (radial k1..k6 as a
    rational function, tangential p1 p2, thin prism s1..s4):
    ``x'' = x' (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6) + 2 p1 x'y' + p2 (r^2 + 2 x'^2)
    + s1 r^2 + s2 r^4`` and likewise for y''; 14 coefficients (tilted sensor) and fisheye lenses go through
    ``cam.project``.
    Like ``cam.project``, NaN beyond the lens model's :attr:`~silpose.shared.pinhole.Camera.max_radius`.
    """
    d = np.zeros(12)
    if cam.dist.size > 12 or cam.fisheye:
        return cam.project(points)
    d[: cam.dist.size] = cam.dist
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d
    xc = cam.to_camera(points)
    # a point in the camera's plane (depth 0) divides by zero: its r2 is inf or NaN, so it gets NaN below
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        x, y = xc[:, 0] / xc[:, 2], xc[:, 1] / xc[:, 2]
        r2 = x * x + y * y
        r4, r6 = r2 * r2, r2 * r2 * r2
        radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4
    K = cam.K
    with np.errstate(invalid="ignore", over="ignore"):
        uv = np.stack([K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=1)
        inside = np.sqrt(r2) < cam.max_radius
    uv[~inside] = np.nan  # beyond the lens model's domain: not seen (Camera.max_radius)
    return uv


def _sees(cam: Camera, boxes: np.ndarray, feet_head: np.ndarray, min_px: float) -> np.ndarray:
    """(N,) bool: every corner of each box (N, 8, 3) in view, and the person (N, 2, 3) tall enough."""
    n = boxes.shape[0]
    xc = cam.to_camera(boxes.reshape(-1, 3))
    depth = xc[:, 2]
    front = depth > MIN_DEPTH_M
    safe = np.where(front, depth, 1.0)
    normal = xc[:, :2] / safe[:, None]
    (lo, hi) = normalised_bounds(cam)
    within = np.all((normal >= lo) & (normal <= hi), axis=1)
    px = project_fast(cam, np.where(front[:, None], boxes.reshape(-1, 3), cam.center + cam.R[2]))
    ok = front & within & cam.in_image(px)
    ok = ok.reshape(n, 8).all(axis=1)
    fh = project_fast(cam, feet_head.reshape(-1, 3)).reshape(n, 2, 2)
    tall = np.linalg.norm(fh[:, 1] - fh[:, 0], axis=1) >= min_px
    return ok & tall


def visibility_grid(cameras, person_height: float = PERSON_HEIGHT_M, footprint: float = DEFAULT_FOOTPRINT_M,
                    step: float = 0.1, min_views: int | None = None,
                    min_person_fraction: float = MIN_PERSON_FRACTION) -> VisibilityGrid:
    """Cells of the floor where a person is fully visible (module docstring).

    The grid spans the floor within reach of the cameras: around each camera, the distance at which
    the person is still ``min_person_fraction`` of its image height (``fy H / (fraction h)``).
    """
    cams = list(cameras)
    k_min = len(cams) if min_views is None else int(min_views)
    reach = [c.K[1, 1] * person_height / (min_person_fraction * c.height) for c in cams]
    lo = np.array([c.center[:2] - r for c, r in zip(cams, reach)])
    hi = np.array([c.center[:2] + r for c, r in zip(cams, reach)])
    if k_min >= len(cams):  # every camera: the intersection of the reaches
        a, b = lo.max(axis=0), hi.min(axis=0)
    else:
        a, b = lo.min(axis=0), hi.max(axis=0)
    if np.any(b <= a):
        a, b = np.minimum(a, b), np.maximum(a, b)
    step = float(max(step, float(np.max(b - a)) / MAX_CELLS_PER_SIDE))
    xs = np.arange(a[0] + step / 2, b[0], step)
    ys = np.arange(a[1] + step / 2, b[1], step)
    X, Y = np.meshgrid(xs, ys)  # (ny, nx)
    centres = np.stack([X.ravel(), Y.ravel()], axis=1)
    h = footprint / 2 + step / 2
    offs = np.array([[sx * h, sy * h, z] for sx in (-1, 1) for sy in (-1, 1) for z in (0.0, person_height)])
    boxes = np.concatenate([centres, np.zeros((len(centres), 1))], axis=1)[:, None, :] + offs[None]
    feet_head = np.stack([np.concatenate([centres, np.zeros((len(centres), 1))], 1),
                          np.concatenate([centres, np.full((len(centres), 1), person_height)], 1)], axis=1)
    per_camera = np.stack([
        _sees(c, boxes, feet_head, min_person_fraction * c.height).reshape(len(ys), len(xs)) for c in cams])
    return VisibilityGrid(xs, ys, step, per_camera, k_min)


def auto_workspace(cameras, **kwargs) -> tuple[Workspace | None, VisibilityGrid]:
    """The largest visible floor rectangle (None if no cell is visible) and the grid it came from.

    ``kwargs`` go to :func:`visibility_grid`.
    """
    grid = visibility_grid(cameras, **kwargs)
    rect = largest_rectangle(grid.visible)
    return (None if rect is None else grid.rectangle_workspace(rect)), grid
