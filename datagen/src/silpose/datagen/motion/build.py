"""Building or extending a motion library from BVH, ASF/AMC, FBX, glTF, TRC or C3D files (``silpose motions import``).

Every file is read by silpose's own importer (Blender's ``io_anim_bvh`` for BVH, its bundled FBX
and glTF importers for those, :mod:`.acclaim` for the CMU database's ASF/AMC, :mod:`.keypoint_clips` for TRC and C3D files of joint keypoints; in
spawned workers, cached by sha256, :mod:`.clips`), mapped onto silpose's roles (:mod:`.joint_maps`, ``"auto"`` or
a given map), thinned to the library's frame rate and stored in the library's own form
(:mod:`.library`). A file that fails (not a BVH file, truncated, a skeleton no map fits, no frame
left) is reported in one line naming the file and skipped; the others go on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..executor import WorkerDied, spawned_map
from .acclaim import CMU_FPS, AcclaimError, clip_sha256, skeleton_of
from .bvh_check import BvhError, check_structure
from .clips import (cache_root, entry_dir, import_into_cache, is_acclaim, is_keypoint_clip, is_scene_clip, read_entry,
                    states_axes)
from .keypoint_clips import KeypointClipError, check_keypoint_clip
from .joint_maps import JointMapError, resolve_map
from .library import DEFAULT_FPS, Library, LibraryError, check_writable, derive_clip, load_library, write_library


@dataclass(frozen=True)
class ClipSource:
    """One BVH or AMC file to import and what the library records about it (``id`` default: the
    stem). ``amc_fps``: the frame rate of an AMC file (which does not state it; CMU's by default)."""

    path: Path
    group: str = "other"
    split: str = "train"
    id: str = ""
    subject: str = ""
    description: str = ""
    licence: str = ""
    source: str = ""
    scale: float = 1.0
    joint_map: str = "auto"
    first: int = 0
    amc_fps: float = CMU_FPS


@dataclass
class ImportReport:
    """What an import did: ``added`` clip ids, ``skipped`` one-line reasons, ``kept`` clips already there."""

    added: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    kept: int = 0


def _import_job(args: tuple[str, str]) -> str | None:
    return import_into_cache(*args)


def cache_all(paths: list[Path], root: Path, workers: int | None,
              progress: Callable[[int, int], None] | None = None) -> dict[Path, str]:
    """Import the files not cached yet; ``{path: one-line error}`` for those that failed (a worker
    crash on one file fails that file only: the rest are retried). ``progress(done, total)`` is called
    with the files to import before the first and after each one (imported or failed)."""
    errors: dict[Path, str] = {}
    done, total = 0, None
    while True:
        todo = []
        for p in paths:
            if p in errors:
                continue
            d = entry_dir(root, clip_sha256(p))
            if not (d / "meta.json").is_file():
                todo.append((str(p), (str(p), str(d))))
        if total is None:
            total = len(todo)
            if progress is not None:
                progress(0, total)
        if not todo:
            return errors
        try:
            for key, error in spawned_map(_import_job, todo, workers, max_tasks_per_child=8):
                if error:
                    errors[Path(key)] = error
                done += 1
                if progress is not None:
                    progress(min(done, total), total)
        except WorkerDied as died:
            errors[Path(died.key)] = f"{died.key}: the importer crashed on this file ({died})"
            done += 1
            if progress is not None:
                progress(min(done, total), total)


def clip_ids(sources: list[ClipSource]) -> dict[Path, str]:
    """Each source's clip id: its ``id``, else the file's stem; stems shared by several files of one
    import take their suffix (``idle.fbx``, ``idle.glb``), then their folder (``walk/idle.fbx``)."""
    def stems(key) -> dict[str, int]:
        out: dict[str, int] = {}
        for s in sources:
            out[key(s)] = out.get(key(s), 0) + 1
        return out

    by_stem, by_name = stems(lambda s: s.path.stem), stems(lambda s: s.path.name)
    ids = {}
    for s in sources:
        if s.id:
            ids[s.path] = s.id
        elif by_stem[s.path.stem] == 1:
            ids[s.path] = s.path.stem
        elif by_name[s.path.name] == 1:
            ids[s.path] = s.path.name
        else:
            ids[s.path] = f"{s.path.parent.name}/{s.path.name}"
    return ids


def check_clip(path: Path) -> None:
    """The checks before importing: a BVH file's structure (:func:`.bvh_check.check_structure`), an
    AMC file's skeleton beside it (:func:`.acclaim.skeleton_of`), a TRC or C3D file's header and marker
    names (:func:`.keypoint_clips.check_keypoint_clip`); FBX and glTF files are checked by their importers. Raises BvhError /
    AcclaimError / KeypointClipError."""
    if is_acclaim(path):
        skeleton_of(path)
    elif is_keypoint_clip(path):
        check_keypoint_clip(path)
    elif not is_scene_clip(path):
        check_structure(path)


def _stride(frame_time: float, fps: float) -> int:
    return max(1, int(round(1.0 / (frame_time * fps)))) if frame_time > 0 else 1


def import_clips(sources: list[ClipSource], folder: Path, fps: float = DEFAULT_FPS, workers: int | None = None,
                 acknowledgement: str | None = None, cache: Path | None = None,
                 progress: Callable[[int, int], None] | None = None) -> ImportReport:
    """Import ``sources`` into the library ``folder``: a new one, or an existing one extended (a
    clip whose id is already there is replaced). Written atomically (:func:`library.write_library`).
    ``progress(done, total)``: the files read so far of those not in the import cache (:func:`cache_all`).

    Raises:
        LibraryError: ``folder`` holds files silpose did not write, or its library is unreadable.
    """
    folder = Path(folder)
    check_writable(folder)
    report = ImportReport()
    old: Library | None = load_library(folder) if (folder / "manifest.json").exists() else None
    root = cache_root() if cache is None else Path(cache)
    ok_sources = []
    for s in sources:
        try:
            check_clip(s.path)
            ok_sources.append(s)
        except (BvhError, AcclaimError, KeypointClipError) as exc:
            report.skipped.append(str(exc))
    errors = cache_all([s.path for s in ok_sources], root, workers, progress)
    ids = clip_ids(ok_sources)
    rows, arrays = [], []
    for s in ok_sources:
        if s.path in errors:
            report.skipped.append(errors[s.path])
            continue
        sha = clip_sha256(s.path)
        arr = read_entry(entry_dir(root, sha))
        meta = dict(arr.meta)
        if is_acclaim(s.path):  # the cache keeps CMU's rate; the rate is the user's to give
            meta["frame_time"] = 1.0 / s.amc_fps
        try:
            jmap = resolve_map(meta["names"], meta["parents"], meta["rest_heads"], meta["rest_tails"], s.joint_map,
                               str(s.path), find_up=not states_axes(s.path))
        except JointMapError as exc:
            report.skipped.append(str(exc))
            continue
        stride = _stride(float(meta["frame_time"]), fps)
        used = np.arange(s.first, int(meta["frames"]), stride, dtype=np.int64)
        if len(used) == 0:
            report.skipped.append(f"{s.path}: no frame left (the clip has {meta['frames']} frames, first kept {s.first})")
            continue
        d = derive_clip(arr, jmap, s.scale, used)
        src_fps = 1.0 / float(meta["frame_time"]) if float(meta["frame_time"]) > 0 else 0.0
        cid = ids[s.path]
        rows.append({"id": cid, "subject": s.subject, "description": s.description, "group": s.group,
                     "split": s.split, "fps": round(src_fps / stride, 3), "source_frames": int(meta["frames"]),
                     "source_fps": round(src_fps, 3), "first": int(s.first), "stride": int(stride),
                     "source": s.source or str(s.path), "licence": s.licence, "sha256": sha,
                     "joint_map": jmap.name, "scale": s.scale, "importer": meta.get("importer", ""),
                     **({"rest_up": jmap.rest_up} if jmap.rest_up != "+z" else {})})
        arrays.append({"frame": used, **d})
        report.added.append(cid)
    if old is not None:
        new_ids = {r["id"] for r in rows}
        keep = [i for i, c in enumerate(old.clips) if c["id"] not in new_ids]
        report.kept = len(keep)
        old_rows = [{k: v for k, v in old.clips[i].items() if k not in ("frames", "lengths", "extent_m")} for i in keep]
        old_arrays = []
        for i in keep:
            r = old.rows(i)
            old_arrays.append({"frame": old.frame[r], "root": old.root[r], "dirs": old.dirs[r],
                               "lengths": np.asarray(old.clips[i]["lengths"]), "extent_m": old.clips[i].get("extent_m", 0.0)})
        rows, arrays = old_rows + rows, old_arrays + arrays
        if acknowledgement is None:
            acknowledgement = old.manifest.get("acknowledgement", "")
    if not rows:
        raise LibraryError(f"{folder}: no clip could be imported ({len(report.skipped)} skipped)")
    write_library(folder, rows, arrays, fps=fps, acknowledgement=acknowledgement or "")
    return report

