"""Which calibration format a file is in, and reading several files into one list of cameras.

=============  ================================================  ==========================================
format         files                                             reader
=============  ================================================  ==========================================
``opencv``     ``*.xml`` / ``*.yml`` / ``*.yaml``                :func:`.opencv.read_opencv`
``easymocap``  ``intri.yml`` + ``extri.yml``                     :func:`.easymocap.read_easymocap`
``pose2sim``   ``*.toml`` (Pose2Sim, anipose)                    :func:`.pose2sim.read_pose2sim`
``skeletool``  ``*.calibration`` (MPI-INF-3DHP, DynaCap)         :func:`.skeletool.read_skeletool`
``colmap``     ``cameras.txt`` + ``images.txt``                  :func:`.colmap.read_colmap`
               (or ``.bin``) of a COLMAP sparse model
``json``       other tools' ``*.json`` (anipose/AIST++, CMU      :func:`.json_layouts.read_json_calibration`
               Panoptic, Human3.6M-style as VoxelPose's)
``silpose``    ``rig.json`` (``silpose rig import``)             :func:`silpose.shared.camera.load_rig`
=============  ================================================  ==========================================

``auto`` picks by name and suffix: ``intri*.yml`` / ``extri*.yml`` -> easymocap, ``.toml`` -> pose2sim,
``.calibration`` (or a file starting with the Skeletool header) -> skeletool, ``cameras.txt`` / ``images.txt`` /
``cameras.bin`` / ``images.bin`` (any case) -> colmap, ``.json`` -> silpose when it is shaped like a rig file
(:func:`silpose.shared.camera.is_rig_dict`), else json; other FileStorage suffixes -> opencv. A pair of files
(EasyMocap's, COLMAP's) is read once, whichever of its files are given.

``translation`` (``--translation``): ``auto`` reads every format's translation as world -> camera, except the
Human3.6M-style JSON records (:mod:`.json_layouts`); ``camera-centre`` reads it as the camera's position in the
world (``x_cam = R (X - t)``) in every file; ``world-to-camera`` as ``x_cam = R X + t`` in every file.
``cameras`` (``--cameras``) keeps the cameras whose names match one of its comma-separated patterns
(``fnmatch``: ``00_*`` keeps CMU Panoptic's HD cameras), in file order.
"""

from __future__ import annotations

import dataclasses
import fnmatch
from pathlib import Path

import numpy as np

from silpose.shared.camera import Rig, RigError, load_rig

from .calibration import CalibratedCamera
from .colmap import colmap_pair, is_colmap, read_colmap
from .easymocap import easymocap_pair, is_easymocap, read_easymocap
from .json_layouts import TRANSLATIONS, is_silpose_rig_json, read_json_calibration
from .opencv import read_opencv
from .pose2sim import read_pose2sim
from .skeletool import is_skeletool, read_skeletool

__all__ = ["FORMATS", "detect_format", "read_calibrations", "select_cameras", "Calibrations"]

FORMATS = ("auto", "opencv", "easymocap", "pose2sim", "skeletool", "colmap", "json", "silpose")
_OPENCV_SUFFIXES = (".xml", ".yml", ".yaml")


def detect_format(path: str | Path) -> str:
    """The format of one file by its name (module docstring); RigError if none fits."""
    p = Path(path)
    suffix = p.suffix.lower()
    if is_easymocap(p):
        return "easymocap"
    if suffix == ".toml":
        return "pose2sim"
    if is_skeletool(p):
        return "skeletool"
    if is_colmap(p):
        return "colmap"
    if suffix == ".json":
        return "silpose" if is_silpose_rig_json(p) else "json"
    if suffix in _OPENCV_SUFFIXES:
        return "opencv"
    raise RigError(f"{p}: unknown calibration format (suffix {suffix or 'none'}); silpose reads OpenCV .xml/.yml/.yaml, "
                   "EasyMocap intri.yml + extri.yml, Pose2Sim/anipose .toml, Skeletool .calibration, "
                   "COLMAP cameras.txt + images.txt (or .bin), JSON calibrations (anipose/AIST++, CMU Panoptic, "
                   "Human3.6M-style) and silpose rig .json (or pass --format)")


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
    paths = [Path(p) for p in paths]
    if not paths:
        raise RigError("rig import: no calibration files given")
    if fmt not in FORMATS:
        raise RigError(f"--format: must be one of {', '.join(FORMATS)}, got {fmt!r}")
    if translation not in TRANSLATIONS:
        raise RigError(f"--translation: must be one of {', '.join(TRANSLATIONS)}, got {translation!r}")
    for p in paths:
        if not p.is_file():
            raise RigError(f"{p}: calibration file not found")
    cams: list[CalibratedCamera] = []
    formats: list[str] = []
    sources: list[str] = []
    rig = None
    notes: list[str] = []
    seen_pairs: set[tuple[str, str]] = set()
    stems = [q.stem for q in paths]
    parents = [q.resolve().parent.name for q in paths]
    stems_of_several = {st for st in stems if stems.count(st) > 1
                        and len({pa for q_st, pa in zip(stems, parents) if q_st == st}) == stems.count(st)}
    for p in paths:
        kind = detect_format(p) if fmt == "auto" else fmt
        formats.append(kind)
        if kind == "silpose":
            if len(paths) > 1:
                raise RigError(f"{p}: a silpose rig file is imported on its own, not with other calibration files")
            rig = load_rig(p)
            cams = [CalibratedCamera(c.name, c.K, c.dist, c.R, c.t, (c.width, c.height), str(p), f"cameras[{i}].")
                    for i, c in enumerate(rig)]
            sources.append(str(p))
            continue
        if kind == "easymocap":
            pair = tuple(str(q) for q in easymocap_pair(p))
            if pair in seen_pairs:
                continue
            seen_pairs.add(pair)
            skipped: list[str] = []
            got = read_easymocap(p, skipped)
            sources += list(pair)
            if skipped:
                notes.append(f"{pair[0]}: camera(s) {', '.join(skipped)} have intrinsics but no extrinsics in "
                             f"{pair[1]}; left out")
        elif kind == "colmap":
            pair = tuple(str(q) for q in colmap_pair(p))
            if pair in seen_pairs:
                continue
            seen_pairs.add(pair)
            got = read_colmap(p, notes)
            sources += list(pair)
        elif kind == "pose2sim":
            got = read_pose2sim(p)
            sources.append(str(p))
        elif kind == "skeletool":
            got = read_skeletool(p)
            sources.append(str(p))
        elif kind == "json":
            got = read_json_calibration(p, translation, notes)
            sources.append(str(p))
        else:
            got = read_opencv(p)
            sources.append(str(p))
            if len(got) == 1 and got[0].name == p.stem and p.stem in stems_of_several:
                # cam1/config.xml, cam2/config.xml ...: one file name in per-camera folders names by the folder
                folder = p.resolve().parent.name
                got = [dataclasses.replace(got[0], name=folder)]
                notes.append(f"{p}: camera named {folder!r} after its folder (every file is {p.name})")
        for c in got:
            twin = next((o for o in cams if o.name == c.name), None)
            if twin is not None:
                raise RigError(f"{c.source}: camera name {c.name!r} is also a camera of {twin.source}; names must be "
                               "unique (a camera is named by its name field, its section, or its file's stem)")
        if translation == "camera-centre" and kind != "json":  # the json reader applies it per record
            got = [dataclasses.replace(c, t=-np.asarray(c.R) @ np.asarray(c.t)) for c in got]
        cams.extend(got)
    if rig is not None and translation != "auto":
        raise RigError(f"{sources[0]}: a silpose rig's poses are silpose's own; drop --translation")
    if cameras is not None:
        cams = select_cameras(cams, cameras)
        notes.append(f"kept {len(cams)} camera(s) matching --cameras {cameras}")
    cams = _one_group(cams, notes)
    return Calibrations(cams, formats, rig, sources, notes)


def _one_group(cams: list[CalibratedCamera], notes: list[str]) -> list[CalibratedCamera]:
    """Cameras of a file holding several poses per camera (``group/name``, e.g. Human3.6M's subjects) must come
    from one group (``--cameras 'S9/*'``); they then take their plain names."""
    grouped = [c for c in cams if c.group is not None]
    groups = sorted({c.group for c in grouped})
    if len(groups) > 1:
        raise RigError(f"{grouped[0].source}: the file holds the cameras' poses for {len(groups)} groups "
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
        raise RigError("--cameras: expected camera names or patterns separated by commas (e.g. 00_00,00_01 or 00_*)")
    names = [c.name for c in cams]
    for w in wanted:
        if not any(fnmatch.fnmatchcase(n, w) for n in names):
            shown = ", ".join(names[:12]) + (f" ... ({len(names)} in all)" if len(names) > 12 else "")
            raise RigError(f"--cameras: {w!r} matches none of the cameras ({shown})")
    return [c for c in cams if any(fnmatch.fnmatchcase(c.name, w) for w in wanted)]
