"""TRC as OpenSim and Pose2Sim read it: a tab-separated marker file, one marker per joint.

Header (OpenSim's ``TRCFileAdapter``): ``PathFileType 4 (X/Y/Z) <file>``, then ``DataRate CameraRate NumFrames
NumMarkers Units OrigDataRate OrigDataStartFrame OrigNumFrames`` and their values, then ``Frame# Time`` and the
marker names (each followed by two empty cells), then ``X1 Y1 Z1 X2 ...``, a blank line, and one row per
frame: 1-based frame number, time in seconds, the markers' coordinates. A frame without joints has empty
cells (OpenSim reads them as missing).

Axes: TRC has no axis field; OpenSim and Pose2Sim expect Y up. silpose's frame (z up) is written as
``(X, Y, Z) = (x, z, -y)``, a rotation: X stays, Y is up. The calibration's frame is written as it is (its
own axes; the file's units are the calibration's). Units: the ``Units`` field (``m``, ``mm`` ...); frame rate:
``DataRate`` and ``CameraRate``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_text_atomic

from .motion import Motion

__all__ = ["write_trc", "trc_coordinates", "Y_UP_FROM_Z_UP"]

#: silpose (x, y, z up) -> TRC (X, Y up, Z): a proper rotation about x.
Y_UP_FROM_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def trc_coordinates(motion: Motion) -> np.ndarray:
    """(T, 19, 3) the coordinates the TRC holds (module docstring: Y up for silpose's frame)."""
    return motion.joints @ Y_UP_FROM_Z_UP.T if motion.frame == "silpose" else motion.joints


def _cell(v: float) -> str:
    return "" if not np.isfinite(v) else f"{v:.6f}"


def write_trc(motion: Motion, path: str | Path) -> Path:
    path = Path(path)
    xyz = trc_coordinates(motion)
    n, k = xyz.shape[:2]
    rate = f"{motion.fps:.6g}"
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        f"{rate}\t{rate}\t{n}\t{k}\t{motion.units}\t{rate}\t{int(motion.frames[0]) + 1}\t{n}",
        "Frame#\tTime\t" + "\t".join(f"{name}\t\t" for name in motion.names).rstrip("\t"),
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, k + 1)),
        "",
    ]
    for f, frame in enumerate(motion.frames):
        t = (frame - motion.frames[0]) / motion.fps
        lines.append(f"{f + 1}\t{t:.6f}\t" + "\t".join(_cell(v) for v in xyz[f].ravel()))
    write_text_atomic(path, "\n".join(lines) + "\n")
    return path
