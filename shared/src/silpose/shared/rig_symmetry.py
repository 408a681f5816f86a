"""Mirror symmetries of a camera rig (docs/conventions.md, "Rig symmetries").

A rig is *mirror-symmetric* about a vertical plane ``P = {X : n . X = c}`` (n a horizontal unit normal,
c metres) when reflecting the world in ``P`` maps every camera onto a camera of the rig with its image
flipped left to right: for every camera a there is a camera b = ``view_map[a]`` with

    project_a(S X) = flip_b(project_b(X))   for every world point X,       S X = X - 2 (n . X - c) n,

where ``flip_b(x, y) = (W_b - 1 - x, y)`` (pixel centres at integer coordinates, docs/conventions.md,
"Contours"). The paper's rig (4 cameras, 45 degrees apart, ``silpose.shared.camera.default_rig``) has one:
the plane half-way between cameras 0 and 3 (and 1 and 2), ``view_map = (3, 2, 1, 0)``. A ring of k
equally spaced cameras has k. Real calibrations are never exactly symmetric, so they have none.

A symmetry gives a second, exact training sample for free: what camera a sees of the *mirrored* person
is what camera ``view_map[a]`` saw of the real one, flipped (``silpose.model.augment.mirror_samples``).

Found by :func:`rig_mirrors`: the candidate planes are the perpendicular bisectors of pairs of camera
centres and the vertical planes through each camera's optical axis; a candidate is kept when the
equation above holds to ``tol_px`` on a grid of points over the workspace from the floor to 2 m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import Rig

__all__ = ["RigMirror", "rig_mirrors", "MIRROR_TOL_PX"]

#: Largest reprojection difference (px) for a plane to count as a rig symmetry. Synthetic rigs agree to
#: 1e-12 px; a camera moved by 1 mm in the default rig differs by about 0.03 px.
MIRROR_TOL_PX = 0.01
#: Heights (metres) of the test grid (floor to the top of a tall person).
_TEST_HEIGHTS = (0.0, 1.0, 2.0)


@dataclass(frozen=True)
class RigMirror:
    """A vertical mirror plane ``n . X = c`` that maps the rig onto itself (module docstring).

    Attributes:
        normal: (3,) horizontal unit normal (z = 0), the sign chosen so its first non-zero entry is > 0.
        offset: c, metres.
        view_map: (V,) ``view_map[a]`` is the camera whose flipped image is camera a's view of the mirrored world.
    """

    normal: tuple[float, float, float]
    offset: float
    view_map: tuple[int, ...]

    def reflect(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) metres reflected in the plane (same shape): ``X - 2 (n . X - c) n``."""
        p = np.asarray(points, dtype=np.float64)
        n = np.asarray(self.normal)
        return p - 2.0 * (p @ n - self.offset)[..., None] * n

    def to_dict(self) -> dict:
        return {"normal": [float(v) for v in self.normal], "offset": float(self.offset),
                "view_map": [int(v) for v in self.view_map]}

    @classmethod
    def from_dict(cls, d: dict) -> "RigMirror":
        """The inverse of :meth:`to_dict`; ValueError naming the field on a malformed entry."""
        try:
            normal = np.asarray(d["normal"], dtype=np.float64)
            offset = float(d["offset"])
            view_map = tuple(int(v) for v in d["view_map"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"rig mirror: needs normal (3 numbers), offset and view_map, got {d!r} ({exc})") from None
        if normal.shape != (3,) or not np.all(np.isfinite(normal)) or abs(np.linalg.norm(normal) - 1) > 1e-9 \
                or abs(normal[2]) > 1e-9:
            raise ValueError(f"rig mirror field normal: must be a horizontal unit vector, got {normal.tolist()}")
        if sorted(view_map) != list(range(len(view_map))):
            raise ValueError(f"rig mirror field view_map: must be a permutation of 0..V-1, got {list(view_map)}")
        if not np.isfinite(offset):
            raise ValueError(f"rig mirror field offset: must be finite, got {offset}")
        return cls(tuple(float(v) for v in normal), offset, view_map)


def _test_points(rig: Rig) -> np.ndarray:
    """(27, 3) points on a 3 x 3 x 3 grid over the workspace (floor rectangle) from 0 to 2 m, metres."""
    (x0, x1), (y0, y1) = rig.workspace.bounds
    g = np.meshgrid(np.linspace(x0, x1, 3), np.linspace(y0, y1, 3), np.asarray(_TEST_HEIGHTS), indexing="ij")
    return np.stack([a.ravel() for a in g], axis=1)


def _canonical_plane(normal: np.ndarray, point: np.ndarray) -> tuple[np.ndarray, float] | None:
    """(unit horizontal normal with a positive first non-zero entry, offset) of the vertical plane through
    ``point`` with horizontal normal ``normal``; None if the normal has no horizontal part."""
    n = np.array([normal[0], normal[1], 0.0])
    length = np.linalg.norm(n)
    if length < 1e-9:
        return None
    n /= length
    if n[0] < -1e-12 or (abs(n[0]) <= 1e-12 and n[1] < 0):
        n = -n
    return n, float(n @ point)


def _candidates(rig: Rig) -> list[tuple[np.ndarray, float]]:
    """Distinct candidate planes: perpendicular bisectors of camera-centre pairs, planes through optical axes."""
    centres = [cam.center for cam in rig]
    planes = []
    for a in range(len(centres)):
        for b in range(a + 1, len(centres)):
            p = _canonical_plane(centres[b] - centres[a], (centres[a] + centres[b]) / 2)
            if p is not None:
                planes.append(p)
        axis = rig[a].R[2]  # the optical axis in world coordinates (third row of R)
        p = _canonical_plane(np.array([-axis[1], axis[0], 0.0]), centres[a])
        if p is not None:
            planes.append(p)
    distinct: list[tuple[np.ndarray, float]] = []
    for n, c in planes:
        if not any(np.allclose(n, m, atol=1e-9) and abs(c - d) < 1e-9 for m, d in distinct):
            distinct.append((n, c))
    return distinct


def rig_mirrors(rig: Rig, tol_px: float = MIRROR_TOL_PX) -> list[RigMirror]:
    """Every vertical mirror plane that maps ``rig`` onto itself (module docstring), in a fixed order.

    A camera may map to itself (the plane contains its optical axis). Cameras of different image sizes
    never map to each other. Returns [] for an asymmetric rig (every real calibration).
    """
    X = _test_points(rig)
    found = []
    for n, c in _candidates(rig):
        mirror = RigMirror(tuple(float(v) for v in n), c, tuple(range(len(rig))))
        reflected = mirror.reflect(X)
        view_map = []
        for cam_a in rig:
            seen = cam_a.project(reflected)
            match = None
            for b, cam_b in enumerate(rig):
                if (cam_b.width, cam_b.height) != (cam_a.width, cam_a.height):
                    continue
                flipped = cam_b.project(X)
                flipped[:, 0] = (cam_b.width - 1) - flipped[:, 0]
                if np.all(np.isfinite(seen)) and np.max(np.abs(seen - flipped)) <= tol_px:
                    match = b
                    break
            if match is None:
                break
            view_map.append(match)
        if len(view_map) == len(rig) and sorted(view_map) == list(range(len(rig))):
            found.append(RigMirror(mirror.normal, mirror.offset, tuple(view_map)))
    return found
