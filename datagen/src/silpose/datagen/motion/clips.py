"""Motion-capture clips on the driver side: import cache, validation, and the clip table.

Each BVH file is imported once by Blender (:func:`silpose.datagen.blender.bvh.import_clip`), each FBX or glTF
file by Blender too (:func:`silpose.datagen.blender.scene_clip.import_scene_clip`, in metres), each AMC file
by :func:`.acclaim.read_clip` (in metres), each TRC or C3D file of joint keypoints by
:func:`.keypoint_clips.read_keypoint_clip` (in metres), in a spawned worker process and its per-frame joint positions are cached by the file's sha256 in
``<cache>/<sha256>-v<CACHE_VERSION>/`` (an AMC file's hash covers its ASF skeleton too) (``heads.npy`` and ``tails.npy``, (F, B, 3) float32 in
the file's unit, and ``meta.json``: joint names, parents, frame count, frame time, rest pose,
importer version; ``meta.json`` is written last, so an entry without it is incomplete and
redone). The cache folder is ``$SILPOSE_CACHE_DIR`` or ``$XDG_CACHE_HOME/silpose`` (default
``~/.cache/silpose``), subfolder ``bvh``; it must be visible to every worker. Render workers
memory-map the arrays and read only the frames they draw.

:func:`prepare_motion` hashes the clips, imports the ones not cached, applies the joint maps and
frame ranges and returns a :class:`PreparedMotion`: what the dataset records (clip names, files,
hashes, frame counts, licences) and what the render workers need (cache folders, maps, frames).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from silpose.shared.atomic import atomic_path, write_json_atomic

from ..blender.bvh import import_clip
from ..blender.scene_clip import SCENE_SUFFIXES, SceneClipError, import_scene_clip
from .acclaim import AcclaimError, clip_sha256, read_clip
from .keypoint_clips import KEYPOINT_SUFFIXES, KeypointClipError, read_keypoint_clip
from .bvh_check import BvhError
from ..executor import WorkerDied, spawned_map
from .joint_maps import ResolvedMap, resolve_map
from .config import ClipSpec, MotionConfig

CACHE_VERSION = 1
CACHE_ENV = "SILPOSE_CACHE_DIR"


class ClipError(ValueError):
    """A clip cannot be used; the message is one line naming the file."""


def cache_root() -> Path:
    """The BVH import cache folder (module docstring)."""
    base = os.environ.get(CACHE_ENV) or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "silpose"
    return Path(base) / "bvh"


def entry_dir(root: Path, sha256: str) -> Path:
    return Path(root) / f"{sha256}-v{CACHE_VERSION}"


@dataclass(frozen=True, eq=False)
class ClipArrays:
    """One cached import: ``meta`` (see :func:`silpose.datagen.blender.bvh.import_clip`), ``heads`` and ``tails``
    (F, B, 3) float32 in the file's unit (memory-mapped when read with ``mmap=True``)."""

    meta: dict
    heads: np.ndarray
    tails: np.ndarray


def read_entry(folder: str | Path, mmap: bool = True) -> ClipArrays:
    """The cached import in ``folder``; ClipError if it is incomplete or damaged."""
    folder = Path(folder)
    try:
        meta = json.loads((folder / "meta.json").read_text())
        mode = "r" if mmap else None
        heads = np.load(folder / "heads.npy", mmap_mode=mode, allow_pickle=False)
        tails = np.load(folder / "tails.npy", mmap_mode=mode, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ClipError(f"{folder}: damaged BVH import cache entry ({type(exc).__name__}: {exc}); delete the folder") from None
    shape = (int(meta["frames"]), len(meta["names"]), 3)
    if heads.shape != shape or tails.shape != shape:
        raise ClipError(f"{folder}: damaged BVH import cache entry (arrays {heads.shape}, meta {shape}); delete the folder")
    return ClipArrays(meta, heads, tails)


def is_acclaim(path: str | Path) -> bool:
    """An AMC clip (CMU's own ASF/AMC format, :mod:`.acclaim`) rather than a BVH file."""
    return Path(path).suffix.lower() == ".amc"


def is_keypoint_clip(path: str | Path) -> bool:
    """A clip of joint keypoints (a TRC or C3D file, :mod:`.keypoint_clips`) rather than a BVH file."""
    return Path(path).suffix.lower() in KEYPOINT_SUFFIXES


def is_scene_clip(path: str | Path) -> bool:
    """An FBX or glTF clip (Blender's bundled importers, :mod:`silpose.datagen.blender.scene_clip`)."""
    return Path(path).suffix.lower() in SCENE_SUFFIXES


def states_axes(path: str | Path) -> bool:
    """A clip file that states its up axis (FBX, glTF: their importers turn it Z up), so its rest pose is not
    used to find up (:func:`.joint_maps.upright_turn`: BVH, ASF/AMC and TRC state none). An animation-only glTF
    has no rest pose but its first frame, which may lie (a clip of someone getting up)."""
    return is_scene_clip(path)


def import_into_cache(path: str, dest: str) -> str | None:
    """Worker task: import ``path`` (a BVH, FBX or glTF file with Blender, an AMC file with
    :mod:`.acclaim`) and write the cache entry ``dest``.

    Returns None, or the one-line error naming the file (never raises: the pool reports it).
    """
    try:
        if is_acclaim(path):
            meta, heads, tails = read_clip(path)
        elif is_keypoint_clip(path):
            meta, heads, tails = read_keypoint_clip(path)
        elif is_scene_clip(path):
            meta, heads, tails = import_scene_clip(path)
        else:
            meta, heads, tails = import_clip(path)
    except (BvhError, AcclaimError, SceneClipError, KeypointClipError) as exc:
        return str(exc)
    except Exception as exc:  # any other failure inside Blender, still one line naming the file
        return f"{path}: import failed ({type(exc).__name__}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else ''})"
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    for name, arr in (("heads.npy", heads), ("tails.npy", tails)):
        with atomic_path(dest / name) as tmp:
            with open(tmp, "wb") as f:
                np.save(f, arr, allow_pickle=False)
    write_json_atomic(dest / "meta.json", {**meta, "source_file": str(path)})
    return None


def ensure_cached(paths: list[Path], root: Path | None = None, workers: int | None = None) -> dict[Path, tuple[str, Path]]:
    """``{path: (sha256, cache folder)}``, importing the clips not cached yet in spawned workers.

    Raises:
        ClipError: the first clip that could not be imported (one line naming the file).
    """
    root = cache_root() if root is None else Path(root)
    out: dict[Path, tuple[str, Path]] = {}
    for p in paths:
        try:
            sha = clip_sha256(Path(p))
        except FileNotFoundError:
            raise ClipError(f"{p}: clip file not found") from None
        except AcclaimError as exc:
            raise ClipError(str(exc)) from None
        out[Path(p)] = (sha, entry_dir(root, sha))
    todo = sorted({d: p for p, (_, d) in out.items() if not (d / "meta.json").is_file()}.items())
    if todo:
        jobs = [(str(p), (str(p), str(d))) for d, p in todo]
        try:
            for _, error in spawned_map(_import_job, jobs, workers, max_tasks_per_child=8):
                if error:
                    raise ClipError(error)
        except WorkerDied as died:
            raise ClipError(f"{died.key}: Blender's BVH importer crashed on this file ({died})") from None
    return out


def _import_job(args: tuple[str, str]) -> str | None:
    """Worker side of :func:`ensure_cached`: ``import_into_cache(path, dest)``."""
    return import_into_cache(*args)


def resolve_frames(first: int, last: int, stride: int, n: int, source: str) -> np.ndarray:
    """The used frame indices of a clip of ``n`` frames (negative ``first``/``last`` from the end)."""
    f, l = (first + n if first < 0 else first), (last + n if last < 0 else last)
    if not (0 <= f <= l < n):
        raise ClipError(f"{source}: frames [{first}, {last}] are outside the clip's {n} frames (0..{n - 1})")
    return np.arange(f, l + 1, stride, dtype=np.int64)


@dataclass(frozen=True, eq=False)
class PreparedClip:
    """A clip ready to draw from: its spec, identity, cache folder, used frames and resolved map."""

    spec: ClipSpec
    name: str
    sha256: str
    cache: Path
    frames: int
    frame_time: float
    used: np.ndarray
    jmap: ResolvedMap
    extent_m: float

    def record(self) -> dict:
        """What the dataset metadata, manifest and card say about this clip."""
        s = self.spec
        return {
            "name": self.name, "file": s.file, "sha256": self.sha256, "frames": self.frames,
            "frame_time": self.frame_time, "used_frames": [int(self.used[0]), int(self.used[-1]), s.stride],
            "n_used": int(len(self.used)), "weight": s.weight, "scale": s.scale, "joint_map": self.jmap.name,
            "vertical_extent_m": round(self.extent_m, 4), "licence": s.licence, "note": s.note,
            **({"rest_up": self.jmap.rest_up} if self.jmap.rest_up != "+z" else {}),
        }

    def worker(self) -> dict:
        """What a render worker needs to pose samples from this clip (:class:`bvh_motion.BvhMotion`)."""
        return {
            "name": self.name, "cache": str(self.cache), "scale": self.spec.scale, "weight": self.spec.weight,
            "used": [int(self.used[0]), int(self.used[-1]), self.spec.stride],
            "map": {"name": self.jmap.name, "index": dict(self.jmap.index), "spine_chain": list(self.jmap.spine_chain),
                    "head_tail": self.jmap.head_tail, "upright": [list(r) for r in self.jmap.upright],
                    "rest_up": self.jmap.rest_up},
        }


@dataclass(frozen=True, eq=False)
class PreparedMotion:
    """The clips of a ``[motion] source = "bvh"`` config, imported and checked."""

    clips: tuple[PreparedClip, ...]
    mirror: bool

    def metadata(self) -> dict:
        """The ``motion`` entry of the dataset config (metadata, manifest, card)."""
        return {"source": "bvh", "mirror": self.mirror, "fields": list(BVH_FIELDS),
                "clips": [c.record() for c in self.clips]}

    def worker(self) -> dict:
        """The ``motion`` entry of the render workers' config."""
        return {"source": "bvh", "mirror": self.mirror, "clips": [c.worker() for c in self.clips]}


#: The per-sample motion parameters of a BVH-driven sample (the ``gait`` column's fields).
BVH_FIELDS: tuple[str, ...] = ("clip", "frame", "mirror", "heading", "x", "y")


def _names(specs: tuple[ClipSpec, ...]) -> list[str]:
    stems = [s.path.stem for s in specs]
    return [st if stems.count(st) == 1 else s.file for st, s in zip(stems, specs)]


def prepare_motion(motion: MotionConfig, workers: int | None = None, root: Path | None = None) -> PreparedMotion:
    """Import (or find in the cache) every clip of ``motion`` and check it (module docstring).

    Raises:
        ClipError / JointMapError: one line naming the clip file.
    """
    cached = ensure_cached([s.path for s in motion.clips], root, workers)
    clips = []
    for spec, name in zip(motion.clips, _names(motion.clips)):
        sha, folder = cached[spec.path]
        arrays = read_entry(folder)
        meta = arrays.meta
        src = str(spec.path)
        jmap = resolve_map(meta["names"], meta["parents"], meta["rest_heads"], meta["rest_tails"], spec.joint_map,
                           src, motion.base, find_up=not states_axes(spec.path))
        used = resolve_frames(spec.frames[0], spec.frames[1], spec.stride, int(meta["frames"]), src)
        sample = used[:: max(1, len(used) // 200)]
        z = np.asarray(arrays.heads[sample], np.float64) @ np.asarray(jmap.upright)[2] * spec.scale  # heights standing
        clips.append(PreparedClip(spec=spec, name=name, sha256=sha, cache=folder, frames=int(meta["frames"]),
                                  frame_time=float(meta["frame_time"]), used=used, jmap=jmap,
                                  extent_m=float(np.max(z.max(axis=1) - z.min(axis=1)))))
    return PreparedMotion(clips=tuple(clips), mirror=motion.mirror)
