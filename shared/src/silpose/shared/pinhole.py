"""One calibrated pinhole camera in the OpenCV convention (docs/conventions.md, "Cameras").

World frame: metres, z up, floor at z = 0. Camera frame: x right, y down, z forward.
Projection: ``x ~ K (R X + t)`` followed by OpenCV lens distortion (zeros for synthetic data).
:mod:`silpose.shared.camera` builds rigs of these cameras and re-exports :class:`Camera` and
:class:`RigError`; the OpenCV calibration reader builds them from files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import cv2
import numpy as np

__all__ = ["Camera", "RigError", "finite_array", "MAX_IMAGE_SIDE"]


class RigError(ValueError):
    """A camera rig is malformed or does not see the workspace."""


def finite_array(value, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (any layout of the same size), all finite; else a
    :class:`RigError` naming ``what`` (e.g. "camera 'cam1' field K")."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise RigError(f"{what}: not numeric ({exc})") from None
    if arr.size != int(np.prod(shape)):
        raise RigError(f"{what}: expected {shape}, got shape {arr.shape}")
    arr = arr.reshape(shape)
    if not np.all(np.isfinite(arr)):
        raise RigError(f"{what}: contains NaN or infinity")
    return arr


#: Largest image width or height (px) a camera may have: 8K UHD (7680 x 4320) fits; a mask of a 4-view
#: sample at the limit is 4 x 8192^2 B = 256 MiB (a typo such as 100000 x 80000 would ask for 30 GiB).
MAX_IMAGE_SIDE = 8192


@dataclass(frozen=True, eq=False)
class Camera:
    """One calibrated camera.

    Attributes:
        name: unique name within a rig.
        K: (3, 3) intrinsic matrix in pixels.
        R: (3, 3) world->camera rotation.
        t: (3,) world->camera translation in metres.
        width, height: image size in pixels.
        dist: (5,) OpenCV distortion coefficients (k1, k2, p1, p2, k3).
    """

    name: str
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))

    def __post_init__(self) -> None:
        what = f"camera {self.name!r}"
        object.__setattr__(self, "K", finite_array(self.K, (3, 3), f"{what} field K"))
        object.__setattr__(self, "R", finite_array(self.R, (3, 3), f"{what} field R"))
        object.__setattr__(self, "t", finite_array(self.t, (3,), f"{what} field t"))
        try:
            dist = np.asarray(self.dist, dtype=np.float64).ravel()
        except (TypeError, ValueError) as exc:
            raise RigError(f"{what} field dist: not numeric ({exc})") from None
        if dist.size not in (4, 5, 8, 12, 14):
            raise RigError(f"{what} field dist: expected 4, 5, 8, 12 or 14 coefficients, got {dist.size}")
        if not np.all(np.isfinite(dist)):
            raise RigError(f"{what} field dist: contains NaN or infinity")
        object.__setattr__(self, "dist", dist)
        if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in (self.width, self.height)):
            raise RigError(f"{what} fields width/height: must be integers")
        if not (0 < self.width <= MAX_IMAGE_SIDE and 0 < self.height <= MAX_IMAGE_SIDE):
            raise RigError(f"{what} fields width/height: must be in 1..{MAX_IMAGE_SIDE} px, got {self.width}x{self.height}")
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))
        if not np.allclose(self.R @ self.R.T, np.eye(3), atol=1e-6) or np.linalg.det(self.R) < 0:
            raise RigError(f"{what} field R: not a rotation matrix")
        if self.K[0, 0] <= 0 or self.K[1, 1] <= 0:
            raise RigError(f"{what} field K: focal lengths must be positive")

    @cached_property
    def K_inv(self) -> np.ndarray:
        """(3, 3) inverse of ``K`` (pixels -> normalised image coordinates), computed once per camera."""
        return np.linalg.inv(self.K)

    @cached_property
    def max_radius(self) -> float:
        """Largest normalised image radius ``r = |(x, y)| / z`` at which the lens model still maps farther
        points farther out (``inf`` without distortion).

        OpenCV's radial model ``r_d = r (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)`` is a
        polynomial fitted inside the calibration images; beyond its first maximum it folds back, and points
        far outside the field of view project into the image (a real calibration with k2 = -1.6 sees a point
        1.6 rad off-axis at its image centre). Found on a grid of 0.001 up to r = 10 (84 deg off-axis)."""
        d = self.dist
        if not np.any(d):
            return float("inf")
        k = np.zeros(8)
        k[: min(d.size, 8)] = d[:8]
        k1, k2, k3, k4, k5, k6 = k[0], k[1], k[4], k[5], k[6], k[7]
        r = np.arange(1, 10001) * 1e-3
        r2 = r * r
        rd = r * (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
        falls = np.flatnonzero(np.diff(rd) <= 0)
        return float(r[falls[0]]) if falls.size else float("inf")

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in world coordinates, metres."""
        return -self.R.T @ self.t

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """World (..., 3) -> camera-frame (..., 3) coordinates, metres."""
        points = np.asarray(points, dtype=np.float64)
        return points @ self.R.T + self.t

    def project(self, points: np.ndarray) -> np.ndarray:
        """Project world points to pixels.

        Args:
            points: (..., 3) world coordinates in metres.
        Returns:
            (..., 2) pixel coordinates (x right, y down; pixel centres at integers); NaN for points beyond
            the lens model's :attr:`max_radius` (not seen: the model folds back there).
        """
        points = np.asarray(points, dtype=np.float64)
        xc = self.to_camera(points)
        if np.any(self.dist) and xc.size:  # (cv2.projectPoints gives None for no points)
            # Project the camera-frame points with a zero pose: going through cv2.Rodrigues(R)
            # would lose ~1e-8 near a rotation angle of pi (the default rig's cam2 has exactly pi).
            flat = np.ascontiguousarray(xc.reshape(-1, 3))
            uv, _ = cv2.projectPoints(flat, np.zeros(3), np.zeros(3), self.K, self.dist)
            uv = uv.reshape(-1, 2)
            with np.errstate(divide="ignore", invalid="ignore"):
                radius = np.hypot(flat[:, 0], flat[:, 1]) / np.abs(flat[:, 2])
            uv[~(radius < self.max_radius)] = np.nan
            return uv.reshape(points.shape[:-1] + (2,))
        z = xc[..., 2:3]
        xy = xc[..., :2] / z
        return xy @ self.K[:2, :2].T + self.K[:2, 2]

    def in_image(self, pixels: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(...,) bool: pixel (..., 2) lies inside the image, ``margin`` pixels from the border."""
        pixels = np.asarray(pixels)
        x, y = pixels[..., 0], pixels[..., 1]
        return (
            (x >= -0.5 + margin)
            & (x <= self.width - 0.5 - margin)
            & (y >= -0.5 + margin)
            & (y <= self.height - 0.5 - margin)
        )

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "K": self.K.tolist(),
            "R": self.R.tolist(),
            "t": self.t.tolist(),
            "width": self.width,
            "height": self.height,
            "dist": self.dist.tolist(),
        }

    @classmethod
    def from_dict(cls, d: dict, source: str = "rig") -> "Camera":
        missing = [k for k in ("name", "K", "R", "t", "width", "height") if k not in d]
        if missing:
            raise RigError(f"{source}: camera entry lacks field(s) {', '.join(missing)}")
        return cls(
            name=str(d["name"]),
            K=d["K"],
            R=d["R"],
            t=d["t"],
            width=d["width"],
            height=d["height"],
            dist=d.get("dist", np.zeros(5)),
        )
