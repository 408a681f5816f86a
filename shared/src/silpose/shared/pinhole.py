"""One calibrated pinhole camera in the OpenCV convention (docs/conventions.md, "Cameras").

World frame: metres, z up, floor at z = 0. Camera frame: x right, y down, z forward.
Projection: ``x ~ K (R X + t)`` followed by OpenCV lens distortion (zeros for synthetic data): the standard model
(``cv2.projectPoints``) or, for a camera with ``fisheye`` set, OpenCV's fisheye model (``cv2.fisheye``, the
Kannala-Brandt polynomial in the angle from the axis, as anipose and COLMAP's ``OPENCV_FISHEYE`` calibrate GoPro-style
lenses).
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
        dist: (5,) OpenCV distortion coefficients (k1, k2, p1, p2, k3); 4, 8, 12 or 14 of them as OpenCV
            reads them; with ``fisheye``, the 4 coefficients (k1, k2, k3, k4) of OpenCV's fisheye model.
        fisheye: the lens follows OpenCV's fisheye model: a point at angle ``theta = atan(r)`` from the axis
            (``r = |(x, y)| / z``) lands at radius ``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 +
            k4 theta^8)`` in normalised image coordinates (OpenCV's ``cv::fisheye`` documentation).
    """

    name: str
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))
    fisheye: bool = False

    def __post_init__(self) -> None:
        what = f"camera {self.name!r}"
        object.__setattr__(self, "K", finite_array(self.K, (3, 3), f"{what} field K"))
        object.__setattr__(self, "R", finite_array(self.R, (3, 3), f"{what} field R"))
        object.__setattr__(self, "t", finite_array(self.t, (3,), f"{what} field t"))
        try:
            dist = np.asarray(self.dist, dtype=np.float64).ravel()
        except (TypeError, ValueError) as exc:
            raise RigError(f"{what} field dist: not numeric ({exc})") from None
        if not isinstance(self.fisheye, (bool, np.bool_)):
            raise RigError(f"{what} field fisheye: expected true or false, got {self.fisheye!r}")
        object.__setattr__(self, "fisheye", bool(self.fisheye))
        if self.fisheye and dist.size != 4:
            raise RigError(f"{what} field dist: a fisheye lens has 4 coefficients (k1, k2, k3, k4), got {dist.size}")
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
        1.6 rad off-axis at its image centre). Found on a grid of 0.001 up to r = 10 (84 deg off-axis). A fisheye
        lens: where ``theta_d(theta)`` first stops growing, on a grid of 1e-4 rad below 90 degrees (``inf`` when it
        grows all the way: every point in front of the camera)."""
        d = self.dist
        if self.fisheye:  # theta_d(theta) on a grid of 1e-4 rad up to the camera's plane (pi / 2)
            theta = np.arange(1, 15708) * 1e-4
            t2 = theta * theta
            theta_d = theta * (1 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))))
            falls = np.flatnonzero(np.diff(theta_d) <= 0)
            return float(np.tan(theta[falls[0]])) if falls.size else float("inf")
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
            the lens model's :attr:`max_radius` (not seen: the model folds back there), and with a fisheye lens
            for points behind the camera.
        """
        points = np.asarray(points, dtype=np.float64)
        xc = self.to_camera(points)
        if self.fisheye and xc.size:
            flat = np.ascontiguousarray(xc.reshape(-1, 1, 3))
            uv, _ = cv2.fisheye.projectPoints(flat, np.zeros(3), np.zeros(3), self.K, self.dist)
            uv = uv.reshape(-1, 2)
            with np.errstate(divide="ignore", invalid="ignore"):
                radius = np.hypot(flat[:, 0, 0], flat[:, 0, 1]) / flat[:, 0, 2]
            uv[~((radius < self.max_radius) & (flat[:, 0, 2] > 0))] = np.nan  # behind the lens: not seen
            return uv.reshape(points.shape[:-1] + (2,))
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

    def normalised(self, pixels: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) -> undistorted normalised image coordinates (..., 2): ``(x / z, y / z)`` of the rays
        they see (``cv2.undistortPoints``, or ``cv2.fisheye.undistortPoints`` for a fisheye lens)."""
        px = np.asarray(pixels, dtype=np.float64)
        flat = np.ascontiguousarray(px.reshape(-1, 1, 2))
        if flat.size == 0:
            return px.copy()
        if self.fisheye:
            n = cv2.fisheye.undistortPoints(flat, self.K, self.dist)
        elif np.any(self.dist):
            n = cv2.undistortPoints(flat, self.K, self.dist)
        else:
            return (px - self.K[:2, 2]) @ np.linalg.inv(self.K[:2, :2]).T
        return n.reshape(px.shape)

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
            **({"fisheye": True} if self.fisheye else {}),
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
            fisheye=d.get("fisheye", False),
        )
