"""Camera rigs in the OpenCV convention: JSON I/O, the default rig, rig files (docs/conventions.md,
"Cameras" and "Default rig").

World frame: metres, z up, floor at z = 0. Camera frame: x right, y down, z forward.
Projection: ``x ~ K (R X + t)`` followed by OpenCV lens distortion (zeros for synthetic data).
One camera is a :class:`Camera` (defined in :mod:`silpose.shared.pinhole`, re-exported here).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from .opencv_calibration import read_opencv_cameras
from .pinhole import Camera, RigError

__all__ = [
    "WORKSPACE_HALF_SIZE",
    "Camera",
    "RigError",
    "Rig",
    "look_at",
    "DEFAULT_RIG_PARAMS",
    "ring_rig",
    "default_rig",
    "load_rig",
]

WORKSPACE_HALF_SIZE = 1.5  # metres: the workspace is [-1.5, 1.5]^2 on the floor


@dataclass(frozen=True, eq=False)
class Rig:
    """An ordered set of calibrated cameras (the views, in shape-vector order)."""

    cameras: tuple[Camera, ...]

    def __post_init__(self) -> None:
        cams = tuple(self.cameras)
        if not cams:
            raise RigError("rig: no cameras")
        names = [c.name for c in cams]
        if len(set(names)) != len(names):
            raise RigError(f"rig: camera names must be unique, got {names}")
        object.__setattr__(self, "cameras", cams)

    def __len__(self) -> int:
        return len(self.cameras)

    def __iter__(self):
        return iter(self.cameras)

    def __getitem__(self, i: int) -> Camera:
        return self.cameras[i]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.cameras)

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) shared by all cameras; raises if they differ."""
        sizes = {(c.width, c.height) for c in self.cameras}
        if len(sizes) != 1:
            raise RigError(f"rig: cameras have different image sizes {sorted(sizes)}")
        return sizes.pop()

    def project(self, points: np.ndarray) -> np.ndarray:
        """World (..., 3) -> (n_cameras, ..., 2) pixels."""
        return np.stack([c.project(points) for c in self.cameras])

    def to_dict(self) -> dict:
        return {"cameras": [c.to_dict() for c in self.cameras]}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_dict(cls, d: dict, source: str = "rig") -> "Rig":
        if not isinstance(d, dict) or not isinstance(d.get("cameras"), list):
            raise RigError(f"{source}: expected an object with a 'cameras' list")
        try:
            cams = []
            for i, c in enumerate(d["cameras"]):
                if not isinstance(c, dict):
                    raise RigError(f"{source}: camera entry {i} is a {type(c).__name__}, expected an object")
                cams.append(Camera.from_dict(c, source))
            return cls(tuple(cams))
        except RigError as exc:  # Camera / Rig checks know the field, not the file
            msg = str(exc)
            raise RigError(msg if msg.startswith(f"{source}: ") else f"{source}: {msg}") from None

    @classmethod
    def from_json(cls, text: str, source: str = "rig") -> "Rig":
        try:
            d = json.loads(text)
        except (json.JSONDecodeError, RecursionError) as exc:
            raise RigError(f"{source}: not valid JSON ({type(exc).__name__}: {exc})") from None
        return cls.from_dict(d, source)

    def check_sees_workspace(self, half_size: float = WORKSPACE_HALF_SIZE, height: float = 0.0) -> None:
        """Raise RigError naming the camera if any corner of the workspace square is not seen.

        Checks the four floor corners (and, with ``height`` > 0, the corners at that height):
        each must be in front of the camera and inside its image.
        """
        zs = [0.0] if height <= 0 else [0.0, height]
        corners = np.array([[sx * half_size, sy * half_size, z] for sx in (-1, 1) for sy in (-1, 1) for z in zs])
        for cam in self.cameras:
            depth = cam.to_camera(corners)[:, 2]
            if np.any(depth <= 0):
                raise RigError(f"camera {cam.name!r}: the workspace is (partly) behind the camera")
            px = cam.project(corners)
            if not np.all(cam.in_image(px)):
                bad = corners[~cam.in_image(px)][0]
                raise RigError(
                    f"camera {cam.name!r}: does not see the workspace corner {bad.round(2).tolist()} "
                    f"(projects to {px[~cam.in_image(px)][0].round(1).tolist()} in a "
                    f"{cam.width}x{cam.height} image)"
                )


def look_at(eye: Sequence[float], target: Sequence[float], up: Sequence[float] = (0.0, 0.0, 1.0)):
    """World->camera (R, t) for a camera at ``eye`` looking at ``target`` (OpenCV axes).

    Returns:
        R: (3, 3) rotation, rows are the camera x (right), y (down), z (forward) axes in world.
        t: (3,) translation, metres.
    """
    eye = np.asarray(eye, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(up, dtype=np.float64))
    if np.linalg.norm(right) < 1e-9:
        raise RigError("look_at: viewing direction is parallel to 'up'")
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    R = np.stack([right, down, forward])
    return R, -R @ eye


#: Default rig parameters (the paper's: 4 cameras, same height, 45 degrees apart, 320x240).
DEFAULT_RIG_PARAMS = {
    "n_cameras": 4,
    "azimuth_start_deg": 0.0,
    "azimuth_step_deg": 45.0,
    "distance_m": 7.0,
    "height_m": 2.2,
    "target_m": (0.0, 0.0, 0.9),
    "focal_px": 470.0,
    "width": 320,
    "height": 240,
}


def ring_rig(
    n_cameras: int = 4,
    azimuth_start_deg: float = 0.0,
    azimuth_step_deg: float = 45.0,
    distance_m: float = 7.0,
    height_m: float = 2.2,
    target_m: Sequence[float] = (0.0, 0.0, 0.9),
    focal_px: float = 470.0,
    width: int = 320,
    height: int = 240,
) -> Rig:
    """Cameras on a horizontal circle around the workspace, all looking at ``target_m``.

    Camera i sits at azimuth ``azimuth_start_deg + i * azimuth_step_deg`` (degrees,
    counter-clockwise from +x), ``distance_m`` from the z axis, ``height_m`` above the floor.
    Principal point at the image centre ((W-1)/2, (H-1)/2), square pixels, no distortion.
    """
    cams = []
    K = np.array([[focal_px, 0, (width - 1) / 2], [0, focal_px, (height - 1) / 2], [0, 0, 1.0]])
    for i in range(n_cameras):
        az = np.deg2rad(azimuth_start_deg + i * azimuth_step_deg)
        eye = (distance_m * np.cos(az), distance_m * np.sin(az), height_m)
        R, t = look_at(eye, target_m)
        cams.append(Camera(name=f"cam{i}", K=K, R=R, t=t, width=width, height=height))
    return Rig(tuple(cams))


def default_rig() -> Rig:
    """The paper's rig: 4 cameras 45 degrees apart at 2.2 m, 7 m from the centre, 320x240.

    Measured: the whole 3 m x 3 m floor is in view of every camera; a 1.75 m person at the
    centre is about 115 px tall (48 % of the image height). Seeing the whole workspace
    diagonal (4.2 m) in a 4:3 image is what limits the size.
    """
    return ring_rig(**DEFAULT_RIG_PARAMS)


def load_rig(path: str | Path | Iterable[str | Path], unit: float = 1.0) -> Rig:
    """Load a rig from a JSON file (``Rig.to_json``) or from OpenCV calibration files.

    Args:
        path: a ``.json`` rig file, or one or more OpenCV ``cv2.FileStorage`` files
            (``.xml``, ``.yml``, ``.yaml``), one camera each, in view order.
        unit: factor converting the OpenCV files' translation unit to metres (0.001 for mm).
    """
    paths = [Path(path)] if isinstance(path, (str, Path)) else [Path(p) for p in path]
    if not paths:
        raise RigError("rig: no files given")
    for p in paths:
        if not p.is_file():
            raise RigError(f"{p}: rig file not found")
    if len(paths) == 1 and paths[0].suffix.lower() == ".json":
        try:
            text = paths[0].read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise RigError(f"{paths[0]}: cannot read the rig file as UTF-8 text ({exc})") from None
        return Rig.from_json(text, source=str(paths[0]))
    cams: list[Camera] = []
    for p in paths:
        cams.extend(read_opencv_cameras(p, unit=unit, default_name=f"cam{len(cams)}"))
    return Rig(tuple(cams))
