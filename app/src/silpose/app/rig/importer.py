"""``silpose rig import``: calibration files in, a silpose rig (cameras, transform, workspace) out.

Steps (each documented in its module):

1. read the cameras (:mod:`.formats`; names from the files, never renumbered);
2. give each its image size (:mod:`.image_size`);
3. build the calibration -> silpose similarity (:mod:`.frame`): unit, up axis (``auto``: the
   cameras' image up), floor (the calibration plane, or ``floor_offset``), origin;
4. check every camera stands above the floor;
5. find the workspace (:mod:`.workspace`; ``auto``: the largest floor rectangle where the tallest
   person is fully visible in ``min_views`` cameras); with ``origin="auto"`` the origin moves to
   the centre of that rectangle, so the workspace is centred at (0, 0) as silpose assumes;
6. check the rig sees its workspace (``Rig.check_sees_workspace``, when every camera is required)
   and shows a 1.75 m person at least ``MIN_PERSON_PX`` tall at its centre.

:func:`import_rig` returns the rig and the notes (what was decided and why) that the command prints.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_text_atomic
from silpose.shared.camera import Camera, Rig, RigError
from silpose.shared.rig_frame import PERSON_HEIGHT_M, Workspace, WorldTransform

from .calibration import CalibratedCamera
from .formats import read_calibrations
from .frame import auto_up, axis_name, make_transform, parse_axis, parse_origin, parse_unit
from .image_size import parse_image_sizes, resolve_image_size
from .workspace import DEFAULT_FOOTPRINT_M, MIN_PERSON_FRACTION, VisibilityGrid, auto_workspace, visibility_grid

__all__ = ["ImportOptions", "ImportResult", "import_rig", "write_rig", "parse_workspace_option", "MIN_PERSON_PX",
           "MANY_CAMERAS",
           "MIN_CAMERA_HEIGHT_M", "MAX_CAMERA_HEIGHT_M"]

#: More cameras than this in one import get a warning pointing to --cameras (a dataset's whole dome).
MANY_CAMERAS = 16
#: Smallest image height (px) of a 1.75 m person at the workspace centre (a wrong unit gives ~0).
MIN_PERSON_PX = 20.0
#: Degrees: when the cameras' image-up directions are this far from the chosen up on average, say so.
UP_DOUBT_DEG = 30.0
#: A camera lower than this above the floor (metres) means the floor or the up axis is wrong.
MIN_CAMERA_HEIGHT_M = 0.2
#: Cameras all higher than this (metres) mean the unit is wrong (millimetres read as metres).
MAX_CAMERA_HEIGHT_M = 50.0


@dataclass
class ImportOptions:
    """The choices of ``silpose rig import`` (strings as typed; parsed by :func:`import_rig`).

    Attributes:
        fmt: ``auto`` or a name in :data:`.formats.FORMATS`.
        translation: ``auto``, ``world-to-camera`` or ``camera-centre`` (:mod:`.formats`).
        cameras: comma-separated camera names or ``fnmatch`` patterns to keep (None: all).
        unit: ``mm``, ``cm``, ``m`` ... or metres per unit (None: metres).
        up: ``auto`` or ``+x`` ... ``-z`` (the calibration's axis pointing up).
        origin: ``auto`` or ``X,Y,Z`` in calibration units (its floor position becomes (0, 0)).
        floor_offset: the floor's coordinate along up, calibration units (0: the calibration plane).
        image_size: ``WxH`` for cameras whose file has no size, or ``name=WxH`` entries per camera (and one bare
            ``WxH`` for the others) (None: look for media next to it).
        workspace: ``auto``, ``WxH`` (metres, centred at the origin) or ``WxH@X,Y`` (centre X, Y metres).
        min_views: cameras that must see a person for ``auto`` (None: all).
        person_height: metres, the tallest person to keep in view.
        footprint: metres, side of the person's square footprint (:data:`.workspace.DEFAULT_FOOTPRINT_M`).
        step: metres, floor cell size of the automatic workspace.
        min_person_fraction: the person's smallest image height, as a fraction of the image height.
    """

    fmt: str = "auto"
    translation: str = "auto"
    cameras: str | None = None
    unit: str | None = None
    up: str = "auto"
    origin: str = "auto"
    floor_offset: float = 0.0
    image_size: str | None = None
    workspace: str = "auto"
    min_views: int | None = None
    person_height: float = PERSON_HEIGHT_M
    footprint: float = DEFAULT_FOOTPRINT_M
    step: float = 0.1
    min_person_fraction: float = MIN_PERSON_FRACTION


@dataclass
class ImportResult:
    """The imported rig, what was decided (one line each) and the visibility grid of the workspace."""

    rig: Rig
    notes: list[str] = field(default_factory=list)
    grid: VisibilityGrid | None = None


def parse_workspace_option(text: str) -> Workspace | None:
    """``auto`` -> None; ``3x2.5`` -> 3 m x 2.5 m at (0, 0); ``3x2.5@0.5,-1`` -> centred at (0.5, -1)."""
    t = str(text).strip().lower()
    if t == "auto":
        return None
    size, _, centre = t.partition("@")
    try:
        w, h = (float(v) for v in size.split("x"))
        c = [float(v) for v in centre.split(",")] if centre else [0.0, 0.0]
        if len(c) != 2:
            raise ValueError
        return Workspace(c, [w, h])
    except ValueError:
        raise RigError(f"--workspace: expected auto, WxH or WxH@X,Y in metres (e.g. 3x2.5@0,0.5), got {text!r}") from None


def _cameras(calib, sizes, transform: WorldTransform) -> list[Camera]:
    out = []
    for c, (w, h) in zip(calib, sizes):
        R, t = transform.camera_to_silpose(c.R, c.t)
        try:
            out.append(Camera(c.name, c.K, R, t, w, h, c.dist, fisheye=c.fisheye))
        except RigError as exc:
            raise RigError(f"{c.source}: {exc}") from None
    return out


def import_rig(paths, options: ImportOptions | None = None) -> ImportResult:
    """Import calibration files as a silpose rig (module docstring). RigError names the file and field."""
    o = options or ImportOptions()
    read = read_calibrations(paths, o.fmt, o.translation, o.cameras)
    calib = read.cameras
    notes = [f"read {len(calib)} camera(s) ({', '.join(c.name for c in calib)}) as {'/'.join(sorted(set(read.formats)))} "
             f"from {', '.join(read.sources)}", *read.notes]
    if len(calib) > MANY_CAMERAS:
        notes.append(f"warning: {len(calib)} cameras: each is a view the generator renders and 400 dimensions of the "
                     f"model's shape vector; keep the ones you record with --cameras (e.g. CMU Panoptic's HD cameras: "
                     f"--cameras '00_*')")
    if read.rig is not None and o.unit not in (None, "m", "1", "1.0"):
        raise RigError(f"{read.sources[0]}: a silpose rig is in metres already; drop --unit")
    scale = 1.0 if o.unit is None else parse_unit(o.unit)
    # a structure-from-motion model has no known unit, up or floor: errors about them say so
    sfm = (" (a COLMAP model's unit, up and floor are arbitrary unless it was aligned with colmap model_aligner)"
           if "colmap" in read.formats else "")
    option_sizes = {} if o.image_size is None else parse_image_sizes(o.image_size, [c.name for c in calib])
    sizes = []
    for c in calib:
        size, how = resolve_image_size(c, option_sizes.get(c.name))
        sizes.append(size)
        if how != "the calibration file":
            notes.append(f"image size of {c.name}: {size[0]}x{size[1]} from {how}")
        cx, cy = c.K[0, 2], c.K[1, 2]
        if not (-0.5 <= cx <= size[0] - 0.5 and -0.5 <= cy <= size[1] - 0.5):
            raise RigError(f"{c.source}: camera {c.name!r}: principal point ({cx:.1f}, {cy:.1f}) lies outside the "
                           f"{size[0]}x{size[1]} image: wrong image size (--image-size WIDTHxHEIGHT)?")
    if o.up == "auto":
        up, agreement = auto_up(calib)
        spread = float(np.degrees(np.arccos(min(1.0, agreement))))
        notes.append(f"up: {axis_name(up)} of the calibration (the cameras' image up is within {spread:.0f} deg of it "
                     "on average; --up to change)")
        if spread > UP_DOUBT_DEG:
            notes.append(f"warning: the cameras disagree about up by {spread:.0f} deg on average (rolled or steeply "
                         "tilted cameras, or no floor in this calibration): check the drawing (--show) and pass --up")
    else:
        up = parse_axis(o.up)
        notes.append(f"up: {axis_name(up)} of the calibration (--up)")
    if not np.isfinite(o.floor_offset):
        raise RigError("--floor-offset: must be a finite number")
    notes.append(f"floor: the calibration plane {axis_name(up)[1]} = {o.floor_offset:g} (calibration units; "
                 "--floor-offset moves it); silpose: z up, metres, floor at z = 0")
    origin = None if o.origin == "auto" else parse_origin(o.origin)
    transform = make_transform(scale, up, o.floor_offset, origin)
    cams = _cameras(calib, sizes, transform)
    for c, cam in zip(calib, cams):
        z = float(cam.center[2])
        if z < MIN_CAMERA_HEIGHT_M and o.floor_offset == 0.0 and _is_camera_frame(c):
            raise RigError(
                f"{c.source}: camera {c.name!r} has the calibration's own axes (no rotation): the world of this "
                "file is that camera's frame (as anipose and Pose2Sim write without a floor reference), so it does "
                "not say where the floor is; pass --floor-offset with the floor's coordinate along up, about minus "
                f"that camera's height ({axis_name(up)} is up; in the file's units: --floor-offset -1500 for a camera "
                f"1.5 m up with --unit mm), and --unit if the distances are not in metres{sfm}"
            )
        if z < MIN_CAMERA_HEIGHT_M:
            raise RigError(
                f"{c.source}: camera {c.name!r} is {abs(z):.2f} m {'below' if z < 0 else 'above'} the floor: silpose "
                f"takes the calibration plane as the floor and {axis_name(up)} as up; pass --up, or --floor-offset "
                f"if the board was not on the floor, or --unit if the distances are not in metres{sfm}"
            )
    heights = np.array([cam.center[2] for cam in cams])
    if np.all(heights > MAX_CAMERA_HEIGHT_M):
        raise RigError(
            f"{read.sources[0]}: the cameras stand {np.median(heights):.0f} m above the floor: the calibration is "
            f"probably not in metres; pass --unit (mm, cm, m or metres per unit){sfm}"
        )
    k = len(cams)
    min_views = k if o.min_views is None else int(o.min_views)
    if not 1 <= min_views <= k:
        raise RigError(f"--min-views: must be between 1 and {k} (the cameras), got {min_views}")
    grid_kwargs = dict(person_height=o.person_height, footprint=o.footprint, step=o.step, min_views=min_views,
                       min_person_fraction=o.min_person_fraction)
    wanted = parse_workspace_option(o.workspace)
    grid = None
    if wanted is None or origin is None:
        ws, grid = auto_workspace(cams, **grid_kwargs)
        if ws is None:
            counts = grid.counts
            blind = [cam.name for cam, seen in zip(cams, grid.per_camera)  # the others agree somewhere, it not there
                     if (others := counts - seen >= min_views - 1).any() and not (seen & others).any()]
            why = (f"camera(s) {', '.join(map(repr, blind))} see a {o.person_height:g} m person nowhere on the floor "
                   "the other cameras see (facing away, or the up axis / unit is wrong?)" if 0 < len(blind) < k else
                   f"no floor spot is seen by {min_views} cameras at once (try --min-views)")
            raise RigError(f"{read.sources[0]}: no workspace: {why}; set it with --origin X,Y,Z and --workspace WxH, "
                           "or draw the cameras with --min-views 1 --show rig.png to see where they look")
        if origin is None:  # the origin moves to the centre of the region all cameras see
            shift = WorldTransform(offset=[-ws.center[0], -ws.center[1], 0.0])
            transform = transform.followed_by(shift)
            cams = _cameras(calib, sizes, transform)
            grid = VisibilityGrid(grid.xs - ws.center[0], grid.ys - ws.center[1], grid.step, grid.per_camera,
                                  grid.min_views)
            o_cal = transform.to_calibration(np.zeros(3))
            notes.append(f"origin: calibration point ({', '.join(f'{v:.4g}' for v in o_cal)}) = the centre of the "
                         f"floor region {min_views} camera(s) see (--origin to change)")
            ws = Workspace([0.0, 0.0], ws.size)
        if wanted is None:
            notes.append(f"workspace: {ws.describe()}, the largest floor rectangle where a {o.person_height:g} m person "
                         f"is fully visible in {'every camera' if min_views == k else f'{min_views} of {k} cameras'} "
                         f"(cells of {grid.step:g} m; --workspace to set it)")
    if origin is not None:
        notes.append(f"origin: calibration point ({', '.join(f'{v:.4g}' for v in origin)}) (--origin)")
    if wanted is not None:
        ws = wanted
        notes.append(f"workspace: {ws.describe()} (--workspace)")
        if grid is None:
            grid = visibility_grid(cams, **grid_kwargs)
    if read.rig is not None:
        transform = read.rig.transform.followed_by(transform)
    rig = Rig(tuple(cams), transform, ws, source=", ".join(str(p) for p in paths))
    if min_views == k:
        rig.check_sees_workspace(height=o.person_height)
    else:
        seen = rig.seen_workspace(height=o.person_height)
        notes.append(f"--min-views {min_views}: some cameras miss parts of the workspace; silpose gen needs every view "
                     "of every sample, so it places its walkers on the part every camera sees: "
                     + (seen.describe() if seen is not None else "none (gen cannot use this rig; infer can)")
                     + "; silpose infer --videos looks for people wherever 2 cameras see them")
    cx, cy = ws.center
    for cam in rig:
        feet, head = cam.project(np.array([[cx, cy, 0.0], [cx, cy, 1.75]]))
        px = float(np.linalg.norm(head - feet))
        if px < MIN_PERSON_PX:
            raise RigError(f"{rig.where}: camera {cam.name!r} shows a 1.75 m person at the workspace centre only "
                           f"{px:.2f} px tall: is the unit right (--unit mm, cm, m){sfm}?")
    return ImportResult(rig, notes, grid)


def write_rig(rig: Rig, out: str | Path) -> Path:
    """Write ``rig`` as JSON (atomically)."""
    return write_text_atomic(Path(out), rig.to_json() + "\n")


def _is_camera_frame(cam: CalibratedCamera) -> bool:
    """True if ``cam``'s axes are the world's (within 2 deg): with a camera standing below the floor this means
    the file's world is that camera's own frame (anipose, Pose2Sim), not a floor's."""
    angle = np.degrees(np.arccos(np.clip((np.trace(np.asarray(cam.R)) - 1.0) / 2.0, -1.0, 1.0)))
    return bool(angle < 2.0)
