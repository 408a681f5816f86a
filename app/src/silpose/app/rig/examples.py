"""Example calibrations for tests, documentation and trying ``silpose rig import`` without a lab.

:func:`one_wall_lab` is the issue's lab: four cameras along one wall of a 6 m x 8 m room, 2 m up,
calibrated with OpenCV against a checkerboard on the floor, in millimetres, z pointing into the
floor, the origin at a board corner. :func:`to_calibration_frame` expresses any silpose rig in such
a frame (the inverse of what ``rig import`` undoes).
"""

from __future__ import annotations

import numpy as np

from silpose.shared.camera import Camera, Rig, look_at
from silpose.shared.rig_frame import WorldTransform

from .calibration import CalibratedCamera

__all__ = ["LAB_DISTORTION", "LAB_IMAGE_SIZE", "one_wall_lab_room", "to_calibration_frame", "one_wall_lab",
           "board_frame"]

LAB_IMAGE_SIZE = (644, 486)
#: A mild wide-angle lens (k1, k2, p1, p2, k3).
LAB_DISTORTION = np.array([-0.18, 0.05, 0.0012, -0.0008, 0.0])


def one_wall_lab_room(focal_px: float = 440.0) -> Rig:
    """The lab in room coordinates (metres, z up): the 8 m wall along x at y = 0, the room 6 m deep
    (y in [0, 6]); cameras 2 m up at x = 1, 3, 5, 7 m, 0.1 m from the wall, all aimed at (4, 3.4, 0.9)."""
    W, H = LAB_IMAGE_SIZE
    K = np.array([[focal_px, 0.0, (W - 1) / 2 + 3.2], [0.0, focal_px * 1.002, (H - 1) / 2 - 2.1], [0.0, 0.0, 1.0]])
    cams = []
    for i, x in enumerate((1.0, 3.0, 5.0, 7.0), start=1):
        R, t = look_at((x, 0.1, 2.0), (4.0, 3.4, 0.9))
        cams.append(Camera(f"cam{i}", K, R, t, W, H, LAB_DISTORTION * (1 + 0.05 * i)))
    return Rig(tuple(cams))


def board_frame(corner=(2.5, 1.5), scale: float = 0.001) -> WorldTransform:
    """Board frame -> room frame: the origin at the board ``corner`` on the floor (room metres), x along
    the room's x, z into the floor (so y = -room y), lengths in millimetres (``scale`` m per unit)."""
    return WorldTransform(np.diag([1.0, -1.0, -1.0]), scale, [corner[0], corner[1], 0.0])


def to_calibration_frame(rig: Rig, frame: WorldTransform, sizes: bool = True) -> list[CalibratedCamera]:
    """``rig``'s cameras with their poses in the calibration frame ``frame`` (calibration -> rig's frame).

    From ``x_cam = R X + t`` (metres) and ``X = s A X_c + b``: the pose in calibration units is
    ``R_c = R A``, ``t_c = (R b + t) / s`` (camera coordinates in calibration units).
    """
    out = []
    for c in rig:
        R_c = c.R @ frame.rotation
        t_c = (c.R @ frame.offset + c.t) / frame.scale
        out.append(CalibratedCamera(c.name, c.K, c.dist, R_c, t_c, (c.width, c.height) if sizes else None, "example"))
    return out


def one_wall_lab(sizes: bool = False) -> tuple[list[CalibratedCamera], WorldTransform]:
    """The lab's cameras in its board frame (mm, z into the floor), and the board -> room transform."""
    frame = board_frame()
    return to_calibration_frame(one_wall_lab_room(), frame, sizes), frame
