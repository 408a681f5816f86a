"""From a calibration's world frame to silpose's: unit, up axis, floor and origin.

silpose's frame (docs/conventions.md, "World frame"): metres, z up, the floor at z = 0, the
workspace on the floor. A calibration's frame is whatever the board defined: millimetres, z into
the floor, the origin at a board corner. The similarity between the two
(:class:`silpose.shared.rig_frame.WorldTransform`, ``X_silpose = s A X_calib + b``) is built from:

- the **unit** ``s`` (metres per calibration unit: ``mm`` 0.001, ``cm`` 0.01, ``m`` 1, or a number);
- the **up axis** ``u``, one of the calibration's axes (``+x`` ... ``-z``). ``auto``: cameras are
  mounted upright, so the image's "up" (camera -y, in world coordinates: ``-R[1]``) of every camera
  points roughly up; ``u`` is the axis with the largest mean cosine to them (:func:`auto_up`). The
  rotation ``A`` has rows ``(a, u x a, u)`` with ``a`` the first calibration axis not along ``u``,
  so silpose's z is ``u`` and the calibration's own horizontal axes are kept (``A = I`` for a z-up
  calibration);
- the **floor**: the calibration plane ``u . X = 0`` (the board lay on the floor), moved to
  ``u . X = floor_offset`` (calibration units) when the board was not on the floor: ``b_z = -s f``;
- the **origin**: a calibration point ``o`` whose floor position becomes silpose's (0, 0)
  (``b_xy = -s (A o)_xy``; its height is ignored), or ``auto``: the centre of the floor region all
  cameras see (:mod:`.workspace`; computed by :mod:`.importer`).
"""

from __future__ import annotations

import numpy as np

from silpose.shared.camera import RigError
from silpose.shared.rig_frame import WorldTransform

from .calibration import CalibratedCamera

__all__ = ["AXES", "UNITS", "parse_unit", "parse_axis", "axis_name", "parse_origin", "auto_up", "frame_rotation",
           "make_transform", "MIN_UP_AGREEMENT"]

AXES: dict[str, np.ndarray] = {
    f"{sign}{name}": s * np.eye(3)[i] for i, name in enumerate("xyz") for sign, s in (("+", 1.0), ("-", -1.0))
}
UNITS = {"mm": 0.001, "cm": 0.01, "dm": 0.1, "m": 1.0, "in": 0.0254, "ft": 0.3048}
#: Smallest mean cosine between the cameras' image up and the chosen axis for ``--up auto``
#: (cos 60 deg): below it the cameras are not upright enough to tell.
MIN_UP_AGREEMENT = 0.5


def parse_unit(text: str) -> float:
    """Metres per calibration unit: ``mm``, ``cm``, ``dm``, ``m``, ``in``, ``ft`` or a positive number."""
    t = str(text).strip().lower()
    if t in UNITS:
        return UNITS[t]
    try:
        v = float(t)
    except ValueError:
        raise RigError(f"--unit: expected one of {', '.join(UNITS)} or metres per unit (e.g. 0.001), got {text!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise RigError(f"--unit: must be a positive number of metres per unit, got {text!r}")
    return v


def parse_axis(text: str, what: str = "--up") -> np.ndarray:
    """``"-z"`` -> (0, 0, -1); ``z`` means ``+z``."""
    t = str(text).strip().lower()
    t = t if t[:1] in "+-" else f"+{t}"
    if t not in AXES:
        raise RigError(f"{what}: expected auto or one of {', '.join(AXES)}, got {text!r}")
    return AXES[t].copy()


def axis_name(v: np.ndarray) -> str:
    return next(k for k, a in AXES.items() if np.array_equal(a, v))


def parse_origin(text: str) -> np.ndarray:
    """``"1200,800,0"`` -> (3,) calibration units."""
    try:
        v = np.array([float(p) for p in str(text).split(",")])
    except ValueError:
        v = np.array([])
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise RigError(f"--origin: expected auto or X,Y,Z in the calibration's units, got {text!r}")
    return v


def auto_up(cameras: list[CalibratedCamera]) -> tuple[np.ndarray, float]:
    """The calibration axis most aligned with every camera's image up (camera -y in world).

    Returns (axis (3,), mean cosine between the cameras' up and it). RigError if the mean cosine
    is below :data:`MIN_UP_AGREEMENT` (cameras rolled or looking straight down).
    """
    ups = np.stack([-np.asarray(c.R)[1] for c in cameras])  # (K, 3), unit vectors
    names = list(AXES)
    scores = np.array([float(np.mean(ups @ AXES[n])) for n in names])
    best = int(np.argmax(scores))
    if scores[best] < MIN_UP_AGREEMENT:
        raise RigError(
            f"{cameras[0].source}: --up auto: the cameras' image 'up' directions agree with no axis "
            f"(best {names[best]}, mean angle {np.degrees(np.arccos(np.clip(scores[best], -1, 1))):.0f} deg): "
            "are they rolled or looking straight down? pass --up (+x, -x, +y, -y, +z or -z)"
        )
    return AXES[names[best]].copy(), float(scores[best])


def frame_rotation(up: np.ndarray) -> np.ndarray:
    """(3, 3) rotation ``A`` with rows ``(a, u x a, u)``: calibration axes -> silpose axes, z = ``up``."""
    u = np.asarray(up, dtype=np.float64)
    a = next(e for e in np.eye(3) if abs(e @ u) < 0.5)
    return np.stack([a, np.cross(u, a), u])


def make_transform(scale: float, up: np.ndarray, floor_offset: float = 0.0,
                   origin: np.ndarray | None = None) -> WorldTransform:
    """The similarity of the module docstring; ``origin`` None keeps the calibration's (0, 0)."""
    A = frame_rotation(up)
    o = np.zeros(3) if origin is None else np.asarray(origin, dtype=np.float64)
    xy = -scale * (A @ o)[:2]
    return WorldTransform(A, scale, np.array([xy[0], xy[1], -scale * floor_offset]))
