"""OpenCV camera <-> Blender camera parameters (horizontal sensor fit). Pure maths, no bpy.

Blender with ``sensor_fit = 'HORIZONTAL'``, image ``W x H``, square pixels (docs/conventions.md, "Cameras"):

    fx = fy = lens / sensor_width * W
    cx = (W - 1) / 2 - shift_x * W
    cy = (H - 1) / 2 + shift_y * W

(the ``(W-1)/2`` puts pixel centres at integer coordinates, OpenCV's convention). Blender's
camera looks down its local -z with +y up, OpenCV's down +z with +y down, so

    camera-to-world (OpenCV axes) = matrix_world @ diag(1, -1, -1, 1)
    matrix_world = inv([R | t; 0 0 0 1]) @ diag(1, -1, -1, 1)      (diag is its own inverse)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from silpose.shared.camera import Camera, RigError

#: Blender's default sensor width in millimetres (any value works; it cancels out).
SENSOR_WIDTH_MM = 36.0
_FLIP = np.diag([1.0, -1.0, -1.0, 1.0])


@dataclass(frozen=True)
class BlenderCameraParams:
    """What a Blender camera object needs.

    Attributes:
        lens: focal length in millimetres.
        sensor_width: sensor width in millimetres (``sensor_fit = 'HORIZONTAL'``).
        shift_x, shift_y: lens shift in units of the image width.
        matrix_world: (4, 4) object matrix (Blender camera axes: -z forward, +y up).
        width, height: render resolution in pixels (``resolution_percentage = 100``).
    """

    lens: float
    sensor_width: float
    shift_x: float
    shift_y: float
    matrix_world: np.ndarray
    width: int
    height: int


def check_blender_compatible(cam: Camera, tol: float = 1e-9) -> None:
    """Raise RigError if ``cam`` cannot be rendered exactly by Blender's pinhole camera.

    Blender needs square pixels (fx == fy), zero skew and no lens distortion.
    """
    K = cam.K
    if abs(K[0, 0] - K[1, 1]) > tol * max(1.0, abs(K[0, 0])):
        raise RigError(
            f"camera {cam.name!r} field K: the Blender renderer needs fx == fy, got fx={K[0, 0]}, fy={K[1, 1]}"
            " (use --renderer raster)"
        )
    if abs(K[0, 1]) > tol or np.any(np.abs(K[2] - (0, 0, 1)) > tol) or np.any(np.abs(K[1, 0]) > tol):
        raise RigError(f"camera {cam.name!r} field K: the Blender renderer needs zero skew and K[2] = (0, 0, 1)")
    if cam.fisheye:
        raise RigError(f"camera {cam.name!r} field fisheye: the Blender renderer cannot render a fisheye lens "
                       "(silhouettes: use --renderer raster; textured frames, gen-frames, need cameras without one)")
    if np.any(cam.dist != 0):
        raise RigError(
            f"camera {cam.name!r} field dist: the Blender renderer cannot render lens distortion "
            f"{cam.dist.tolist()} (silhouettes: use --renderer raster; textured frames, gen-frames, need cameras "
            "without distortion)"
        )


def to_blender(cam: Camera, sensor_width: float = SENSOR_WIDTH_MM) -> BlenderCameraParams:
    """OpenCV camera -> Blender camera parameters (see the module docstring)."""
    check_blender_compatible(cam)
    W, H = cam.width, cam.height
    fx, cx, cy = cam.K[0, 0], cam.K[0, 2], cam.K[1, 2]
    Rt = np.eye(4)
    Rt[:3, :3] = cam.R
    Rt[:3, 3] = cam.t
    return BlenderCameraParams(
        lens=float(fx * sensor_width / W),
        sensor_width=float(sensor_width),
        shift_x=float(((W - 1) / 2 - cx) / W),
        shift_y=float((cy - (H - 1) / 2) / W),
        matrix_world=np.linalg.inv(Rt) @ _FLIP,
        width=W,
        height=H,
    )


def from_blender(params: BlenderCameraParams, name: str = "cam") -> Camera:
    """Blender camera parameters -> OpenCV camera (inverse of :func:`to_blender`)."""
    W, H = int(params.width), int(params.height)
    f = params.lens / params.sensor_width * W
    K = np.array([[f, 0, (W - 1) / 2 - params.shift_x * W], [0, f, (H - 1) / 2 + params.shift_y * W], [0, 0, 1.0]])
    cam_to_world = np.asarray(params.matrix_world, dtype=np.float64) @ _FLIP
    # matrix_world may carry scale; keep the rotation only (orthonormalise via SVD)
    U, _, Vt = np.linalg.svd(cam_to_world[:3, :3])
    Rc2w = U @ Vt
    R = Rc2w.T
    t = -R @ cam_to_world[:3, 3]
    return Camera(name=name, K=K, R=R, t=t, width=W, height=H)
