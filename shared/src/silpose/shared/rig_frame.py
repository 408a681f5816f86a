"""Where a rig lives: the transform from a calibration's own world frame to silpose's, and the workspace.

silpose's world frame (docs/conventions.md, "World frame"): metres, z up, floor at z = 0, the
walking area (workspace) on the floor. A lab's calibration has its own frame — millimetres, z pointing
into the floor, origin at a checkerboard corner. :class:`WorldTransform` is the similarity between
the two, stored with the rig so every output can be given back in the lab's own frame::

    X_silpose = scale * A @ X_calib + offset          X_calib = A.T @ (X_silpose - offset) / scale

with ``A`` a rotation (3, 3), ``scale`` metres per calibration unit and ``offset`` (3,) metres.
:class:`Workspace` is the floor rectangle where people walk, in silpose's frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .pinhole import finite_array

__all__ = ["WorldTransform", "Workspace", "DEFAULT_WORKSPACE", "PERSON_HEIGHT_M"]

#: Height (metres) of the tallest person a workspace must hold in view: the test split's tallest
#: stature (1.98 m, ``silpose.datagen.subjects``) rounded up. Rig checks and the automatic workspace
#: use it (a test keeps it above every configured stature).
PERSON_HEIGHT_M = 2.0


@dataclass(frozen=True, eq=False)
class WorldTransform:
    """Similarity from a calibration's world frame to silpose's (z up, metres, floor z = 0).

    Attributes:
        rotation: (3, 3) proper rotation ``A`` (calibration axes -> silpose axes).
        scale: metres per calibration unit (0.001 for millimetres), > 0.
        offset: (3,) metres, added after rotation and scaling.
    """

    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    scale: float = 1.0
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        A = finite_array(self.rotation, (3, 3), "transform field rotation")
        if not np.allclose(A @ A.T, np.eye(3), atol=1e-6) or np.linalg.det(A) < 0:
            raise ValueError("transform field rotation: not a proper rotation matrix")
        try:
            s = float(self.scale)
        except (TypeError, ValueError):
            s = float("nan")
        if isinstance(self.scale, bool) or not np.isfinite(s) or s <= 0:
            raise ValueError(f"transform field scale: must be a positive number, got {self.scale!r}")
        object.__setattr__(self, "rotation", A)
        object.__setattr__(self, "scale", s)
        object.__setattr__(self, "offset", finite_array(self.offset, (3,), "transform field offset"))

    @property
    def is_identity(self) -> bool:
        return bool(np.allclose(self.rotation, np.eye(3)) and self.scale == 1.0 and not np.any(self.offset))

    def to_silpose(self, points: np.ndarray) -> np.ndarray:
        """Calibration-frame (..., 3) points (calibration units) -> silpose (..., 3) metres."""
        p = np.asarray(points, dtype=np.float64)
        return self.scale * (p @ self.rotation.T) + self.offset

    def to_calibration(self, points: np.ndarray) -> np.ndarray:
        """silpose (..., 3) metres -> calibration-frame (..., 3) points in calibration units."""
        p = np.asarray(points, dtype=np.float64)
        return ((p - self.offset) @ self.rotation) / self.scale

    def camera_to_silpose(self, R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A world->camera pose in the calibration frame (R (3, 3), t (3,) in calibration units)
        -> the same camera's world->camera pose in silpose's frame (R', t' in metres).

        From ``x_cam = R X_c + t`` and ``X_c = A^T (X - b) / s``: ``R' = R A^T``,
        ``t' = s t - R A^T b`` (camera coordinates rescaled to metres).
        """
        R = np.asarray(R, dtype=np.float64)
        t = np.asarray(t, dtype=np.float64)
        R2 = R @ self.rotation.T
        return R2, self.scale * t - R2 @ self.offset

    def followed_by(self, other: "WorldTransform") -> "WorldTransform":
        """The transform applying ``self`` then ``other``: ``other.to_silpose(self.to_silpose(X))``.

        ``s2 A2 (s1 A1 X + b1) + b2 = (s2 s1) (A2 A1) X + (s2 A2 b1 + b2)``.
        """
        return WorldTransform(other.rotation @ self.rotation, other.scale * self.scale,
                              other.scale * (other.rotation @ self.offset) + other.offset)

    @property
    def up_in_calibration(self) -> np.ndarray:
        """(3,) unit vector: silpose's up (+z) expressed in the calibration's axes (``A^T e_z``)."""
        return self.rotation[2].copy()

    def to_dict(self) -> dict:
        return {"rotation": self.rotation.tolist(), "scale": self.scale, "offset": self.offset.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "WorldTransform":
        if not isinstance(d, dict):
            raise ValueError("transform: expected an object with rotation, scale, offset")
        unknown = sorted(set(d) - {"rotation", "scale", "offset"})
        if unknown:
            raise ValueError(f"transform: unknown field(s) {', '.join(map(str, unknown))}")
        return cls(d.get("rotation", np.eye(3)), d.get("scale", 1.0), d.get("offset", np.zeros(3)))


@dataclass(frozen=True, eq=False)
class Workspace:
    """The floor rectangle where people walk, axis-aligned in silpose's frame.

    Attributes:
        center: (2,) metres, the rectangle's centre (x, y) on the floor.
        size: (2,) metres, its extent along x and y (both > 0).
    """

    center: np.ndarray = field(default_factory=lambda: np.zeros(2))
    size: np.ndarray = field(default_factory=lambda: np.array([3.0, 3.0]))

    def __post_init__(self) -> None:
        c = finite_array(self.center, (2,), "workspace field center")
        s = finite_array(self.size, (2,), "workspace field size")
        if np.any(s <= 0):
            raise ValueError(f"workspace field size: must be positive, got {s.tolist()}")
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "size", s)

    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((x_min, x_max), (y_min, y_max)) in metres."""
        lo, hi = self.center - self.size / 2, self.center + self.size / 2
        return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))

    def corners(self, z: float = 0.0) -> np.ndarray:
        """(4, 3) floor corners at height ``z`` metres, counter-clockwise from (x_min, y_min)."""
        (x0, x1), (y0, y1) = self.bounds
        return np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """(...,) bool: floor points (..., 2) metres inside the rectangle (borders included)."""
        xy = np.asarray(xy, dtype=np.float64)
        (x0, x1), (y0, y1) = self.bounds
        return (xy[..., 0] >= x0) & (xy[..., 0] <= x1) & (xy[..., 1] >= y0) & (xy[..., 1] <= y1)

    def describe(self) -> str:
        """One line, e.g. ``3.00 m x 3.00 m centred at (0.00, 0.00) m``."""
        return (f"{self.size[0]:.2f} m x {self.size[1]:.2f} m centred at "
                f"({self.center[0]:.2f}, {self.center[1]:.2f}) m")

    @property
    def is_default(self) -> bool:
        """True for the built-in 3 m x 3 m square centred at the origin."""
        return self.to_dict() == DEFAULT_WORKSPACE.to_dict()

    def to_dict(self) -> dict:
        return {"center": self.center.tolist(), "size": self.size.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "Workspace":
        if not isinstance(d, dict) or "size" not in d:
            raise ValueError("workspace: expected an object with 'size' (and optionally 'center')")
        unknown = sorted(set(d) - {"center", "size"})
        if unknown:
            raise ValueError(f"workspace: unknown field(s) {', '.join(map(str, unknown))}")
        return cls(d.get("center", np.zeros(2)), d["size"])


#: The built-in rig's workspace: a 3 m x 3 m square centred at the origin.
DEFAULT_WORKSPACE = Workspace()
