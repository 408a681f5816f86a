"""Camera rigs in the OpenCV convention: JSON I/O, the default rig, rig files (docs/conventions.md,
"Cameras", "World frame" and "Default rig").

World frame: metres, z up, floor at z = 0. Camera frame: x right, y down, z forward.
Projection: ``x ~ K (R X + t)`` followed by OpenCV lens distortion (zeros for synthetic data).
One camera is a :class:`Camera` (defined in :mod:`silpose.shared.pinhole`, re-exported here).

A :class:`Rig` also carries where it lives (:mod:`silpose.shared.rig_frame`): the similarity from
the calibration's own frame to silpose's (``transform``), the floor rectangle people walk in
(``workspace``) and the file it came from (``source``, named by every error). ``silpose rig import``
(``silpose.app.rig``) writes rig files from calibrations; this module reads and writes silpose's
JSON only.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from .pinhole import Camera, RigError
from .rectangles import largest_rectangle
from .rig_frame import Workspace, WorldTransform

__all__ = [
    "Camera",
    "RigError",
    "Rig",
    "look_at",
    "DEFAULT_RIG_PARAMS",
    "ring_rig",
    "default_rig",
    "load_rig",
    "is_rig_dict",
    "CONVENTION",
]

#: What silpose assumes about a rig's world frame, quoted by the errors that teach it.
CONVENTION = "silpose assumes z up, metres, the floor at z = 0 and people walking inside the rig's workspace"
#: Calibration file suffixes that ``silpose rig import`` reads (``load_rig`` refuses them with a hint).
CALIBRATION_SUFFIXES = (".xml", ".yml", ".yaml", ".toml", ".calibration")
_RIG_KEYS = {"cameras", "transform", "workspace", "source"}
_CAMERA_KEYS = {"name", "K", "R", "t", "width", "height", "dist", "fisheye"}


def is_rig_dict(d) -> bool:
    """True when ``d`` (parsed JSON) is shaped like a silpose rig file: an object of rig fields only, whose
    ``cameras`` list holds objects of silpose camera fields only. Other tools' JSON calibrations (CMU Panoptic,
    AIST++, VoxelPose ...) are not, and go to ``silpose rig import``."""
    if not isinstance(d, dict) or not isinstance(d.get("cameras"), list) or not set(d) <= _RIG_KEYS:
        return False
    return all(isinstance(c, dict) and set(c) <= _CAMERA_KEYS for c in d["cameras"])


@dataclass(frozen=True, eq=False)
class Rig:
    """An ordered set of calibrated cameras (the views, in shape-vector order) and where they live.

    Attributes:
        cameras: the cameras, in view order.
        transform: calibration frame -> silpose frame similarity (identity for rigs made in silpose).
        workspace: the floor rectangle where people walk (default: 3 m x 3 m centred at the origin).
        source: the file(s) the rig was read or imported from ("" for built-in rigs); errors name it.
    """

    cameras: tuple[Camera, ...]
    transform: WorldTransform = field(default_factory=WorldTransform)
    workspace: Workspace = field(default_factory=Workspace)
    source: str = ""

    def __post_init__(self) -> None:
        cams = tuple(self.cameras)
        if not cams:
            raise RigError(f"{self.where}: no cameras")
        names = [c.name for c in cams]
        if len(set(names)) != len(names):
            raise RigError(f"{self.where}: camera names must be unique, got {names}")
        if not isinstance(self.transform, WorldTransform) or not isinstance(self.workspace, Workspace):
            raise RigError(f"{self.where}: transform/workspace must be WorldTransform/Workspace objects")
        object.__setattr__(self, "cameras", cams)
        object.__setattr__(self, "source", str(self.source))

    @property
    def where(self) -> str:
        """The name errors start with: the source file, or ``rig``."""
        return self.source or "rig"

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
            raise RigError(f"{self.where}: cameras have different image sizes {sorted(sizes)}")
        return sizes.pop()

    def project(self, points: np.ndarray) -> np.ndarray:
        """World (..., 3) -> (n_cameras, ..., 2) pixels."""
        return np.stack([c.project(points) for c in self.cameras])

    def with_workspace(self, workspace: Workspace) -> "Rig":
        """The same rig with another workspace."""
        return dataclasses.replace(self, workspace=workspace)

    def to_dict(self) -> dict:
        """``{"cameras": [...]}`` plus ``transform``, ``workspace`` and ``source`` when they differ from
        the defaults (identity, 3 m x 3 m centred, none), so the built-in rig's dict is unchanged."""
        d: dict = {"cameras": [c.to_dict() for c in self.cameras]}
        if not self.transform.is_identity:
            d["transform"] = self.transform.to_dict()
        if not self.workspace.is_default:
            d["workspace"] = self.workspace.to_dict()
        if self.source:
            d["source"] = self.source
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_dict(cls, d: dict, source: str | None = None) -> "Rig":
        """A rig from :meth:`to_dict`'s dict; ``source`` names errors (default: the dict's own
        ``source``). ``Rig.source`` is the dict's ``source`` (``load_rig`` sets the file it read)."""
        where = source or (d.get("source") if isinstance(d, dict) and isinstance(d.get("source"), str) else "") or "rig"
        if not isinstance(d, dict) or not isinstance(d.get("cameras"), list):
            raise RigError(f"{where}: expected an object with a 'cameras' list")
        unknown = sorted(map(str, set(d) - _RIG_KEYS))
        if unknown:
            raise RigError(f"{where}: unknown field(s) {', '.join(unknown)}; known: {', '.join(sorted(_RIG_KEYS))}")
        try:
            cams = []
            for i, c in enumerate(d["cameras"]):
                if not isinstance(c, dict):
                    raise RigError(f"{where}: camera entry {i} is a {type(c).__name__}, expected an object")
                cams.append(Camera.from_dict(c, where))
            try:
                transform = WorldTransform.from_dict(d["transform"]) if "transform" in d else WorldTransform()
                workspace = Workspace.from_dict(d["workspace"]) if "workspace" in d else Workspace()
            except ValueError as exc:
                raise RigError(f"{where}: {exc}") from None
            stored = d.get("source", "")
            if not isinstance(stored, str):
                raise RigError(f"{where}: field source: expected a string")
            return cls(tuple(cams), transform, workspace, stored)
        except RigError as exc:  # Camera / Rig checks know the field, not the file
            msg = str(exc)
            raise RigError(msg if msg.startswith(f"{where}: ") else f"{where}: {msg}") from None

    @classmethod
    def from_json(cls, text: str, source: str | None = None) -> "Rig":
        try:
            d = json.loads(text)
        except (json.JSONDecodeError, RecursionError) as exc:
            raise RigError(f"{source or 'rig'}: not valid JSON ({type(exc).__name__}: {exc})") from None
        return cls.from_dict(d, source)

    def check_sees_workspace(self, height: float = 0.0, workspace: Workspace | None = None) -> None:
        """Raise RigError unless every camera sees every corner of the workspace.

        Checks the four floor corners of ``workspace`` (default: the rig's) and, with ``height`` > 0
        metres, the four corners at that height: each must be in front of the camera and inside its
        image. The one-line error names the rig's file, the camera, the corner and where it projects,
        says what silpose assumes (:data:`CONVENTION`) and how to fix the frame.
        """
        ws = self.workspace if workspace is None else workspace
        corners = np.concatenate([ws.corners(z) for z in ([0.0] if height <= 0 else [0.0, height])])
        for cam in self.cameras:
            depth = cam.to_camera(corners)[:, 2]
            px = cam.project(corners)
            ok = _in_view(cam, corners)
            if np.all(ok):
                continue
            i = int(np.flatnonzero(~ok)[0])
            if depth[i] <= 0:
                where = "is behind the camera"
            elif not np.all(np.isfinite(px[i])):
                where = (f"lies {np.degrees(np.arctan(cam.max_radius)):.0f} deg or more off the camera's axis, beyond "
                         "where its lens distortion model is valid")
            else:
                where = f"projects to {px[i].round(1).tolist()} in a {cam.width}x{cam.height} image"
            raise RigError(
                f"{self.where}: camera {cam.name!r} does not see the workspace corner "
                f"{corners[i].round(2).tolist()} m ({where}); {CONVENTION} ({ws.describe()}); "
                "re-import the calibration with `silpose rig import` and the right --unit, --up, --origin "
                "or --workspace, and look at it with `silpose rig show`"
            )


    def seen_workspace(self, height: float = 0.0, step: float = 0.05) -> Workspace | None:
        """The largest axis-aligned part of the workspace that every camera sees (None: no part).

        The workspace is cut into equal cells about ``step`` metres wide (whole cells: n = ceil(size / step)
        per side); a cell is seen when the corners of its box, from the floor to ``height`` metres, pass the
        test of :meth:`check_sees_workspace` in every camera (in front of it, inside its image), and the
        answer is the largest rectangle of seen cells (:func:`silpose.shared.rectangles.largest_rectangle`).
        Its corners are corners of seen cells, so ``check_sees_workspace(height, workspace=answer)`` passes.
        The whole workspace when every camera sees it. ``silpose gen`` places its walkers there on a rig whose
        workspace some camera misses (``silpose rig import --min-views``), while people are still looked for
        on the whole floor the cameras see (docs/conventions.md, "World frame").
        """
        ws = self.workspace
        if all(np.all(_in_view(cam, np.concatenate([ws.corners(0.0), ws.corners(height)]))) for cam in self.cameras):
            return ws
        n = np.maximum(1, np.ceil(ws.size / float(step) - 1e-9)).astype(int)  # (nx, ny) cells
        (x0, x1), (y0, y1) = ws.bounds
        xe, ye = np.linspace(x0, x1, n[0] + 1), np.linspace(y0, y1, n[1] + 1)  # cell edges, metres
        X, Y = np.meshgrid(xe, ye)  # (ny + 1, nx + 1) cell corners
        corner_ok = np.ones(X.shape, bool)
        for z in (0.0, float(height)):
            pts = np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], axis=1)
            for cam in self.cameras:
                corner_ok &= _in_view(cam, pts).reshape(X.shape)
        cells = corner_ok[:-1, :-1] & corner_ok[1:, :-1] & corner_ok[:-1, 1:] & corner_ok[1:, 1:]  # (ny, nx)
        rect = largest_rectangle(cells)
        if rect is None:
            return None
        r0, r1, c0, c1 = rect
        lo, hi = np.array([xe[c0], ye[r0]]), np.array([xe[c1 + 1], ye[r1 + 1]])
        return Workspace(np.round((lo + hi) / 2, 9), np.round(hi - lo, 9))  # free of the float sums' 1e-17 m


def _in_view(cam: Camera, points: np.ndarray) -> np.ndarray:
    """(N,) bool: world points (N, 3) metres in front of ``cam`` and projecting inside its image."""
    depth = cam.to_camera(points)[:, 2]
    return (depth > 0) & cam.in_image(cam.project(points))

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


def load_rig(path: str | Path) -> Rig:
    """Load a rig file written by :meth:`Rig.to_json` (``silpose rig import`` writes them).

    Calibration files of other tools (OpenCV XML/YAML, EasyMocap, Pose2Sim/anipose TOML) are
    refused with a hint: ``silpose rig import`` converts them (units, up axis, origin, workspace).
    The rig's ``source`` is ``path``; every error names it.
    """
    p = Path(path)
    if not p.is_file():
        raise RigError(f"{p}: rig file not found")
    if p.suffix.lower() in CALIBRATION_SUFFIXES:
        raise RigError(
            f"{p}: a calibration file, not a silpose rig; convert it first with "
            f"`silpose rig import {p} --out rig.json` (options --unit, --up, --origin, --image-size)"
        )
    try:
        text = p.read_text(encoding="utf-8-sig")  # past a Windows editor's byte-order mark
    except (OSError, UnicodeDecodeError) as exc:
        raise RigError(f"{p}: cannot read the rig file as UTF-8 text ({exc})") from None
    try:
        rig = Rig.from_json(text, source=str(p))
    except RigError as exc:
        try:
            foreign = not is_rig_dict(json.loads(text))
        except (ValueError, RecursionError):
            foreign = False
        if foreign:  # another tool's JSON calibration (CMU Panoptic, AIST++, VoxelPose ...)
            raise RigError(f"{exc}; if this is a calibration file of another tool, convert it with "
                           f"`silpose rig import {p} --out rig.json`") from None
        raise
    return dataclasses.replace(rig, source=str(p))
