"""C3D through the ``c3d`` library: POINT data, one point per joint, stored as floats.

Units: ``POINT:UNITS`` (``m``, ``mm`` ...); frame rate: ``POINT:RATE``; axes: ``POINT:X_SCREEN`` /
``POINT:Y_SCREEN`` say which axis points right and which up on screen (``+X`` / ``+Z`` for silpose's z-up
frame; for the calibration's frame, its up axis). The labels are silpose's joint names; a frame without joints
has its points marked invalid (residual -1, coordinates 0), as C3D readers expect.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from silpose.shared.atomic import atomic_path

from .motion import Motion

__all__ = ["write_c3d"]


def _screen_axes(up: str) -> tuple[str, str]:
    axis = up[-1].upper() if up and up[-1] in "xyz" else "Z"
    sign = "-" if up.startswith("-") else "+"
    right = {"X": "+Y", "Y": "+X", "Z": "+X"}[axis]
    return right, sign + axis


def write_c3d(motion: Motion, path: str | Path) -> Path:
    import c3d

    path = Path(path)
    writer = c3d.Writer(point_rate=float(motion.fps), point_scale=-1.0, point_units=f"{motion.units:<4}")
    writer.set_point_labels(list(motion.names))
    x_screen, y_screen = _screen_axes(motion.up)
    writer.set_screen_axis(X=x_screen, Y=y_screen)
    writer.set_start_frame(int(motion.frames[0]) + 1)
    empty = np.zeros((0, 0), np.float32)
    frames = []
    for xyz in motion.joints:
        points = np.zeros((len(motion.names), 5), np.float32)
        ok = np.isfinite(xyz).all(axis=1)
        points[ok, :3] = xyz[ok]
        points[~ok, 3] = -1.0  # invalid
        frames.append((points, empty))
    writer.add_frames(frames)
    with atomic_path(path) as tmp, open(tmp, "wb") as handle, warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="No analog data")  # point data only, by design
        writer.write(handle)
    return path
