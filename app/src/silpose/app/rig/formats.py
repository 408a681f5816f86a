"""The calibration formats ``silpose rig import`` reads: one registry, :data:`FORMATS`.

Each entry is a :class:`Format`: a name (``--format``), what its files look like and which tools write
them (``rig import --help``, the "unknown format" error and the README's table are generated from these),
``detect(path) -> bool`` and ``read(path, ctx) -> list[CalibratedCamera]``, one signature for all. ``auto``
tries the entries' ``detect`` in registry order (the first match wins, so the catch-all OpenCV suffixes come
last). A format whose calibration is several files (EasyMocap's pair, COLMAP's) gives ``files(path)``: the
whole set, read once whichever of its files are given. Adding a format is one entry here (its reader in its
own module, imported lazily so ``silpose --help`` stays light) and its test.

``translation`` (``--translation``): ``auto`` reads every format's translation as world -> camera, except the
Human3.6M-style JSON records (:mod:`.json_layouts`); ``camera-centre`` reads it as the camera's position in the
world (``x_cam = R (X - t)``) in every file; ``world-to-camera`` as ``x_cam = R X + t`` in every file.
``cameras`` (``--cameras``) keeps the cameras whose names match one of its comma-separated patterns
(``fnmatch``: ``00_*`` keeps CMU Panoptic's HD cameras), in file order.
"""

from __future__ import annotations

import dataclasses
import fnmatch
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    from silpose.shared.camera import Rig

    from .calibration import CalibratedCamera

__all__ = ["Format", "ReadContext", "FORMATS", "FORMAT_NAMES", "format_choices", "formats_table", "get_format",
           "detect_format", "read_calibrations", "select_cameras", "Calibrations"]


@dataclass
class ReadContext:
    """What a reader may use besides its file, and where it leaves what it found besides cameras.

    Attributes:
        paths: every file of this import (a reader may name a camera after its folder when several files share
            one name).
        translation: ``--translation`` (module docstring); readers with ``own_translation`` apply it themselves.
        notes: lines the command prints (a reader appends what it decided).
        rig: set by the ``silpose`` reader: the rig file read whole.
    """

    paths: list[Path]
    translation: str = "auto"
    notes: list[str] = field(default_factory=list)
    rig: Rig | None = None


@dataclass(frozen=True)
class Format:
    """One calibration format (module docstring).

    Attributes:
        name: the ``--format`` value.
        files: what its files look like, for help and the README (``intri.yml + extri.yml``).
        tools: who writes them.
        detect: ``detect(path) -> bool``: the file is in this format (by name; may peek at the first line).
        read: ``read(path, ctx) -> cameras``: every camera of the file (or of its set of files).
        files_of: the whole set of files ``path`` belongs to (read once), or None for one file.
        own_translation: the reader applies ``ctx.translation`` itself (else ``camera-centre`` is applied after).
    """

    name: str
    files: str
    tools: str
    detect: Callable[[Path], bool]
    read: Callable[[Path, ReadContext], "list[CalibratedCamera]"]
    files_of: Callable[[Path], tuple[Path, ...]] | None = None
    own_translation: bool = False


def _error(message: str) -> Exception:
    """A RigError (imported here: silpose.shared.camera brings numpy and OpenCV, which ``--help`` does not need)."""
    from silpose.shared.camera import RigError

    return RigError(message)


# --- the readers, each importing its module when used ---------------------------------------------------------

def _easymocap_detect(p: Path) -> bool:
    return p.name.lower().startswith(("intri", "extri")) and p.suffix.lower() in (".yml", ".yaml")


def _easymocap_files(p: Path) -> tuple[Path, ...]:
    from .easymocap import easymocap_pair

    return tuple(easymocap_pair(p))


def _easymocap_read(p: Path, ctx: ReadContext):
    from .easymocap import easymocap_pair, read_easymocap

    skipped: list[str] = []
    got = read_easymocap(p, skipped)
    if skipped:
        intri, extri = easymocap_pair(p)
        ctx.notes.append(f"{intri}: camera(s) {', '.join(skipped)} have intrinsics but no extrinsics in {extri}; "
                         "left out")
    return got


def _pose2sim_read(p: Path, ctx: ReadContext):
    from .pose2sim import read_pose2sim

    return read_pose2sim(p)


def _skeletool_detect(p: Path) -> bool:
    from .skeletool import is_skeletool

    return is_skeletool(p)


def _skeletool_read(p: Path, ctx: ReadContext):
    from .skeletool import read_skeletool

    return read_skeletool(p)


def _qualisys_detect(p: Path) -> bool:
    from .qualisys import is_qualisys

    return is_qualisys(p)


def _qualisys_read(p: Path, ctx: ReadContext):
    from .qualisys import read_qualisys

    return read_qualisys(p, ctx.notes)


_COLMAP_NAMES = ("cameras.txt", "images.txt", "cameras.bin", "images.bin")


def _colmap_files(p: Path) -> tuple[Path, ...]:
    from .colmap import colmap_pair

    return tuple(colmap_pair(p))


def _colmap_read(p: Path, ctx: ReadContext):
    from .colmap import read_colmap

    return read_colmap(p, ctx.notes)


def _silpose_detect(p: Path) -> bool:
    from .json_layouts import is_silpose_rig_json

    return p.suffix.lower() == ".json" and is_silpose_rig_json(p)


def _silpose_read(p: Path, ctx: ReadContext):
    from silpose.shared.camera import load_rig

    from .calibration import CalibratedCamera

    if len(ctx.paths) > 1:
        raise _error(f"{p}: a silpose rig file is imported on its own, not with other calibration files")
    if ctx.translation != "auto":
        raise _error(f"{p}: a silpose rig's poses are silpose's own; drop --translation")
    ctx.rig = load_rig(p)
    return [CalibratedCamera(c.name, c.K, c.dist, c.R, c.t, (c.width, c.height), str(p), f"cameras[{i}].")
            for i, c in enumerate(ctx.rig)]


def _json_read(p: Path, ctx: ReadContext):
    from .json_layouts import read_json_calibration

    return read_json_calibration(p, ctx.translation, ctx.notes)


def _opencv_read(p: Path, ctx: ReadContext):
    from .opencv import read_opencv

    got = read_opencv(p)
    same_name = [q for q in ctx.paths if q.stem == p.stem]
    if (len(got) == 1 and got[0].name == p.stem and len(same_name) > 1
            and len({q.resolve().parent.name for q in same_name}) == len(same_name)):
        # cam1/config.xml, cam2/config.xml ...: one file name in per-camera folders names by the folder
        folder = p.resolve().parent.name
        got = [dataclasses.replace(got[0], name=folder)]
        ctx.notes.append(f"{p}: camera named {folder!r} after its folder (every file is {p.name})")
    return got


#: Every format, in the order ``auto`` tries them.
FORMATS: tuple[Format, ...] = (
    Format("easymocap", "intri.yml + extri.yml", "EasyMocap", _easymocap_detect, _easymocap_read,
           files_of=_easymocap_files),
    Format("pose2sim", "*.toml", "Pose2Sim, anipose (fisheye lenses too)", lambda p: p.suffix.lower() == ".toml", _pose2sim_read),
    Format("skeletool", "*.calibration", "Skeletool, Captury (MPI-INF-3DHP, DynaCap)", _skeletool_detect,
           _skeletool_read),
    Format("qualisys", "*.qca.txt (XML)", "Qualisys Track Manager (Pose2Sim's demos)", _qualisys_detect,
           _qualisys_read),
    Format("colmap", "cameras.txt + images.txt (or .bin)", "COLMAP sparse model", lambda p: p.name.lower() in
           _COLMAP_NAMES, _colmap_read, files_of=_colmap_files),
    Format("silpose", "rig.json", "silpose rig import", _silpose_detect, _silpose_read),
    Format("json", "*.json", "anipose/AIST++, CMU Panoptic, Human3.6M-style (VoxelPose's Shelf/Campus)",
           lambda p: p.suffix.lower() == ".json", _json_read, own_translation=True),
    Format("opencv", "*.xml, *.yml, *.yaml (one per camera or one for all)", "OpenCV cv2.FileStorage",
           lambda p: p.suffix.lower() in (".xml", ".yml", ".yaml"), _opencv_read),
)
FORMAT_NAMES: tuple[str, ...] = tuple(f.name for f in FORMATS)


def format_choices() -> str:
    """``auto, easymocap, ... or opencv``: the ``--format`` values."""
    names = ("auto",) + FORMAT_NAMES
    return ", ".join(names[:-1]) + " or " + names[-1]


def formats_summary() -> str:
    """One sentence listing every format's files and tools (help texts, errors)."""
    return "; ".join(f"{f.tools}: {f.files}" for f in FORMATS)


def formats_table() -> str:
    """The Markdown table of the formats (README)."""
    rows = ["| `--format` | files | written by |", "|---|---|---|"]
    rows += [f"| `{f.name}` | {f.files} | {f.tools} |" for f in FORMATS]
    return "\n".join(rows)


def get_format(name: str) -> Format:
    """The registry entry ``name``; RigError naming the known formats."""
    for f in FORMATS:
        if f.name == name:
            return f
    raise _error(f"--format: must be one of {format_choices()}, got {name!r}")


def detect_format(path: str | Path) -> str:
    """The name of the first format whose ``detect`` accepts ``path``; RigError listing them if none does."""
    p = Path(path)
    for f in FORMATS:
        if f.detect(p):
            return f.name
    raise _error(f"{p}: unknown calibration format (suffix {p.suffix.lower() or 'none'}); silpose reads "
                   f"{formats_summary()} (or pass --format)")


class Calibrations:
    """The cameras read from the files, with the format used and, for a silpose rig file, that rig."""

    def __init__(self, cameras: list[CalibratedCamera], formats: list[str], rig: Rig | None, sources: list[str],
                 notes: list[str] | None = None):
        self.cameras = cameras
        self.formats = formats
        self.rig = rig
        self.sources = sources
        self.notes = notes or []


def read_calibrations(paths, fmt: str = "auto", translation: str = "auto", cameras: str | None = None) -> Calibrations:
    """Every camera of ``paths`` (one or more files), in file order then camera order.

    Camera names come from the files (never renumbered) and must be unique across them. Per-camera files that
    share one name in different folders (``cam1/config.xml``, ``cam2/config.xml``: a common course and lab
    layout) and have no name field are named by their folders.
    """
    from .json_layouts import TRANSLATIONS

    paths = [Path(p) for p in paths]
    if not paths:
        raise _error("rig import: no calibration files given")
    forced = None if fmt == "auto" else get_format(fmt)
    if translation not in TRANSLATIONS:
        raise _error(f"--translation: must be one of {', '.join(TRANSLATIONS)}, got {translation!r}")
    for p in paths:
        if not p.is_file():
            raise _error(f"{p}: calibration file not found")
    ctx = ReadContext(paths=paths, translation=translation)
    cams: list[CalibratedCamera] = []
    formats: list[str] = []
    sources: list[str] = []
    seen: set[tuple[str, ...]] = set()
    for p in paths:
        kind = forced or get_format(detect_format(p))
        formats.append(kind.name)
        files = tuple(str(q) for q in kind.files_of(p)) if kind.files_of else (str(p),)
        if files in seen:
            continue
        seen.add(files)
        got = kind.read(p, ctx)
        sources += list(files)
        for c in got:
            twin = next((o for o in cams if o.name == c.name), None)
            if twin is not None:
                raise _error(f"{c.source}: camera name {c.name!r} is also a camera of {twin.source}; names must be "
                               "unique (a camera is named by its name field, its section, or its file's stem)")
        if translation == "camera-centre" and not kind.own_translation:
            import numpy as np

            got = [dataclasses.replace(c, t=-np.asarray(c.R) @ np.asarray(c.t)) for c in got]
        cams.extend(got)
    if cameras is not None:
        cams = select_cameras(cams, cameras)
        ctx.notes.append(f"kept {len(cams)} camera(s) matching --cameras {cameras}")
    cams = _one_group(cams, ctx.notes)
    return Calibrations(cams, formats, ctx.rig, sources, ctx.notes)


def _one_group(cams: list[CalibratedCamera], notes: list[str]) -> list[CalibratedCamera]:
    """Cameras of a file holding several poses per camera (``group/name``, e.g. Human3.6M's subjects) must come
    from one group (``--cameras 'S9/*'``); they then take their plain names."""
    grouped = [c for c in cams if c.group is not None]
    groups = sorted({c.group for c in grouped})
    if len(groups) > 1:
        raise _error(f"{grouped[0].source}: the file holds the cameras' poses for {len(groups)} groups "
                       f"({', '.join(groups)}): keep one with --cameras '{groups[0]}/*'")
    if not groups:
        return cams
    plain = [c.name[len(c.group) + 1:] if c.group is not None and c.name.startswith(c.group + "/") else c.name
             for c in cams]
    if len(set(plain)) != len(plain):
        return cams
    notes.append(f"cameras of group {groups[0]} named {', '.join(plain)}")
    return [dataclasses.replace(c, name=n, group=None) for c, n in zip(cams, plain)]


def select_cameras(cams: list[CalibratedCamera], patterns: str) -> list[CalibratedCamera]:
    """The cameras whose names match one of the comma-separated ``fnmatch`` patterns, in their order;
    RigError when a pattern matches none (naming the cameras there are)."""
    wanted = [w.strip() for w in str(patterns).split(",") if w.strip()]
    if not wanted:
        raise _error("--cameras: expected camera names or patterns separated by commas (e.g. 00_00,00_01 or 00_*)")
    names = [c.name for c in cams]
    for w in wanted:
        if not any(fnmatch.fnmatchcase(n, w) for n in names):
            shown = ", ".join(names[:12]) + (f" ... ({len(names)} in all)" if len(names) > 12 else "")
            raise _error(f"--cameras: {w!r} matches none of the cameras ({shown})")
    return [c for c in cams if any(fnmatch.fnmatchcase(c.name, w) for w in wanted)]
