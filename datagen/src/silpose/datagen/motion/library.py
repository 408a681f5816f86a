"""The motion library: motion-capture clips stored as silpose's own derived data (pure numpy and
pyarrow, no bpy).

A library is a folder holding exactly two files, both written by silpose (atomically):

- ``manifest.json``: ``format`` (:data:`FORMAT`), ``version``, ``acknowledgement`` (text a dataset
  card must show), ``roles`` and ``parents`` (the role tree below), ``fps`` (the rate frames were
  thinned to) and ``clips``: one row per clip with ``id``, ``subject``, ``description``, ``group``
  (activity group), ``split`` (``train`` / ``test``: held-out *subjects*, never frames), ``fps``,
  ``frames`` (frames kept), ``source_frames`` and ``source_fps`` (the BVH file's), ``first`` and
  ``stride`` (kept frames are ``first + k * stride``), ``source`` (where the BVH file came from),
  ``licence``, ``sha256`` (of the source BVH file), ``joint_map``, ``scale`` (metres per BVH unit),
  ``lengths`` (metres, one per non-root role: the clip's own segment lengths, medians over its kept
  frames) and ``extent_m`` (the clip's largest vertical joint extent, metres: a check of ``scale``);
- ``frames.parquet``: one row per kept frame, in clip order: ``clip`` (int32, row of ``clips``),
  ``frame`` (int32, 0-based BVH frame), ``root`` (4 float32: the pelvis position in metres, z up,
  and the yaw of the hip line's forward direction, radians counter-clockwise from +x: the clip's
  root motion) and ``dirs`` (3 x 20 float32: the unit direction, world axes, of every non-root
  role from its parent; NaN for a role the clip lacks).

Roles (:data:`ROLES`, parent in brackets): pelvis; spine_1 .. spine_3 (pelvis, spine_1, spine_2),
the clip's spine chain between pelvis and neck resampled to 3 interior points at 1/4, 1/2, 3/4 of
its arc length (kept exactly when the chain has exactly 3 interior joints, none where its parent is,
as the Character Creator skeleton's); neck (spine_3); head (neck); head_top (head); per side
shoulder (neck), elbow, wrist and hip (pelvis), knee, ankle, toe. A frame's joint positions are
``root[:3]`` plus the cumulative sums of ``dirs * lengths`` down the tree, so the library stores
every clip's bone directions and root motion, and nothing of the source file itself.

Clips are read by silpose's own importer (Blender's ``io_anim_bvh``, :mod:`.clips`) and mapped with
:mod:`.joint_maps`; frames are thinned to :data:`DEFAULT_FPS` (every ``round(source_fps / fps)``-th
frame). At generation time no Blender import runs: render workers read the arrays and retarget
(:mod:`.retarget`) exactly as for a BVH clip (:class:`LibraryClip`).
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from silpose.shared.atomic import TMP_GLOB, atomic_path, write_json_atomic

from ..manifest import sha256_file
from .clips import ClipArrays
from .joint_maps import OPTIONAL_ROLES, REQUIRED_ROLES, ResolvedMap
from .retarget import clip_points, heading_of, polyline_point

FORMAT = "silpose-motion-library"
VERSION = 1
MANIFEST_NAME = "manifest.json"
FRAMES_NAME = "frames.parquet"
LIBRARY_FILES = frozenset({MANIFEST_NAME, FRAMES_NAME})
#: Frame rate the clips are thinned to (poses, not dynamics, are what silhouettes need).
DEFAULT_FPS = 30.0
#: The library shipped inside the package (built by ``scripts/build_motion_library.py``).
BUNDLED = Path(__file__).resolve().parent / "library"

#: The CMU database's licence and the acknowledgement it asks for (a card of a dataset using its clips shows it).
CMU_LICENCE = "CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu): free for research and commercial use"
CMU_ACKNOWLEDGEMENT = ("The data used in this project was obtained from mocap.cs.cmu.edu. "
                       "The database was created with funding from NSF EIA-0196217.")

_SIDE = ("shoulder", "elbow", "wrist", "hip", "knee", "ankle", "toe")
#: The library's role tree (module docstring): names and parent indices.
ROLES: tuple[str, ...] = ("pelvis", "spine_1", "spine_2", "spine_3", "neck", "head", "head_top",
                          *(f"l_{j}" for j in _SIDE), *(f"r_{j}" for j in _SIDE))
_IDX = {r: i for i, r in enumerate(ROLES)}


def _parent(role: str) -> int:
    fixed = {"pelvis": -1, "spine_1": 0, "spine_2": 1, "spine_3": 2, "neck": 3, "head": 4, "head_top": 5}
    if role in fixed:
        return fixed[role]
    side, joint = role.split("_", 1)
    up = {"shoulder": "neck", "elbow": f"{side}_shoulder", "wrist": f"{side}_elbow", "hip": "pelvis",
          "knee": f"{side}_hip", "ankle": f"{side}_knee", "toe": f"{side}_ankle"}[joint]
    return _IDX[up]


PARENTS: tuple[int, ...] = tuple(_parent(r) for r in ROLES)
N_ROLES = len(ROLES)
N_BONES = N_ROLES - 1
CHAIN: tuple[int, ...] = (0, 1, 2, 3, 4)


class LibraryError(ValueError):
    """A library folder or file cannot be used; the message is one line naming the file and field."""


# ------------------------------------------------------------------------------------------ derive


#: Shortest spine-chain segment (metres) kept as a joint of its own (:func:`resample_chain`).
MIN_SEGMENT_M = 1e-4


def resample_chain(chain: np.ndarray) -> np.ndarray:
    """(F, k, 3) spine chains (metres) -> (F, 5, 3): kept when k == 5 and no segment is shorter than
    :data:`MIN_SEGMENT_M` in any frame, else the points at 0, 1/4, ..., 1 of each chain's arc length
    (the MotionBuilder-friendly CMU skeleton's LowerBack and Neck start where their parents do:
    kept as they are, two roles would have no direction)."""
    if chain.shape[1] == 5 and np.all(np.linalg.norm(np.diff(chain, axis=1), axis=2) >= MIN_SEGMENT_M):
        return chain
    return np.stack([np.stack([polyline_point(c, f) for f in (0.0, 0.25, 0.5, 0.75, 1.0)]) for c in chain])


def role_positions(heads: np.ndarray, tails: np.ndarray, jmap: ResolvedMap) -> np.ndarray:
    """(F, 21, 3) role positions (:data:`ROLES`) of clip frames (heads/tails (F, B, 3), metres);
    NaN rows for optional roles the clip lacks."""
    F = heads.shape[0]
    out = np.full((F, N_ROLES, 3), np.nan)
    chains = []
    for k in range(F):
        pts = clip_points(heads[k], tails[k], jmap, mirror=False)
        chains.append(pts.pop("chain"))
        for r, p in pts.items():
            if r in _IDX:
                out[k, _IDX[r]] = p
    out[:, list(CHAIN)] = resample_chain(np.asarray(chains, np.float64))
    return out


def derive(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(root (F, 4), dirs (F, 20, 3), lengths (20,))`` of role positions (F, 21, 3), metres.

    ``root`` = pelvis xyz and the hip line's yaw (:func:`retarget.heading_of`); ``dirs`` the unit
    vectors parent -> role (NaN where a role is missing); ``lengths`` their median lengths.
    """
    P = np.asarray(positions, np.float64)
    vec = P[:, 1:] - P[:, list(PARENTS[1:])]
    norm = np.linalg.norm(vec, axis=2)
    dirs = vec / np.where(norm > 1e-12, norm, np.nan)[..., None]
    with warnings.catch_warnings():  # a role the clip lacks (toes) has no length: 0 below
        warnings.simplefilter("ignore", RuntimeWarning)
        lengths = np.nanmedian(np.where(np.isfinite(norm), norm, np.nan), axis=0) if len(P) else np.zeros(N_BONES)
    lengths = np.where(np.isfinite(lengths), lengths, 0.0)
    yaw = np.array([heading_of(p[_IDX["l_hip"]] - p[_IDX["r_hip"]]) for p in P])
    root = np.concatenate([P[:, 0], yaw[:, None]], axis=1)
    return root, dirs, lengths


def reconstruct(root: np.ndarray, dirs: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """(F, 21, 3) role positions from ``root``, ``dirs`` and ``lengths`` (inverse of :func:`derive`)."""
    root, dirs = np.asarray(root, np.float64), np.asarray(dirs, np.float64)
    P = np.zeros((len(root), N_ROLES, 3))
    P[:, 0] = root[:, :3]
    for c in range(1, N_ROLES):
        P[:, c] = P[:, PARENTS[c]] + dirs[:, c - 1] * float(lengths[c - 1])
    return P


def derive_clip(arrays: ClipArrays, jmap: ResolvedMap, scale: float, used: np.ndarray) -> dict:
    """The library form of a cached BVH import: ``root``, ``dirs``, ``lengths``, ``extent_m`` of its
    frames ``used`` (metres: BVH unit times ``scale``)."""
    heads = np.asarray(arrays.heads[used], np.float64) * scale
    tails = np.asarray(arrays.tails[used], np.float64) * scale
    P = role_positions(heads, tails, jmap)
    root, dirs, lengths = derive(P)
    z = heads @ np.asarray(jmap.upright)[2]  # heights once the clip stands (joint_maps.upright_turn)
    return {"root": root, "dirs": dirs, "lengths": lengths,
            "extent_m": float(np.max(z.max(axis=1) - z.min(axis=1))) if len(z) else 0.0}


# ------------------------------------------------------------------------------------------- files


@dataclass(frozen=True, eq=False)
class Library:
    """A loaded library: ``folder``, ``manifest`` (dict), ``clip`` (N,) int32, ``frame`` (N,) int32,
    ``root`` (N, 4) float32, ``dirs`` (N, 20, 3) float32 (module docstring)."""

    folder: Path
    manifest: dict
    clip: np.ndarray
    frame: np.ndarray
    root: np.ndarray
    dirs: np.ndarray

    @property
    def clips(self) -> list[dict]:
        return self.manifest["clips"]

    def rows(self, c: int) -> slice:
        """The frame rows of clip ``c`` (contiguous, in frame order)."""
        lo, hi = np.searchsorted(self.clip, [c, c + 1])
        return slice(int(lo), int(hi))

    def positions(self, c: int) -> np.ndarray:
        """(F, 21, 3) role positions of clip ``c``'s kept frames (metres)."""
        r = self.rows(c)
        return reconstruct(self.root[r], self.dirs[r], np.asarray(self.clips[c]["lengths"]))

    def sha256(self) -> str:
        """sha256 of the frames file (recorded with every dataset made from this library)."""
        return sha256_file(self.folder / FRAMES_NAME)


def _check_manifest(m, path: Path) -> dict:
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        raise LibraryError(f"{path}: field 'format' must be {FORMAT!r} (not a silpose motion library)")
    if m.get("version") != VERSION:
        raise LibraryError(f"{path}: field 'version' is {m.get('version')!r}; this silpose reads version {VERSION}")
    if list(m.get("roles", [])) != list(ROLES):
        raise LibraryError(f"{path}: field 'roles' differs from this silpose's role tree")
    if not isinstance(m.get("clips"), list):
        raise LibraryError(f"{path}: field 'clips' must be a list")
    for i, c in enumerate(m["clips"]):
        for key in ("id", "group", "split", "licence", "frames", "lengths"):
            if key not in c:
                raise LibraryError(f"{path}: clips[{i}]: field {key!r} missing")
        if len(c["lengths"]) != N_BONES:
            raise LibraryError(f"{path}: clips[{i}] ({c['id']}): field 'lengths' must hold {N_BONES} numbers")
    return m


_CACHE: dict[tuple[str, float], Library] = {}


def load_library(folder: str | Path | None = None) -> Library:
    """The library in ``folder`` (default: :data:`BUNDLED`), cached per process by path and mtime.

    Raises:
        LibraryError: one line naming the file and the field.
    """
    folder = Path(BUNDLED if folder in (None, "", "bundled") else folder).expanduser()
    mpath, fpath = folder / MANIFEST_NAME, folder / FRAMES_NAME
    try:
        key = (str(fpath.resolve()), fpath.stat().st_mtime)
    except FileNotFoundError:
        raise LibraryError(f"{fpath}: motion library file not found (build one with `silpose motions import`)") from None
    if key in _CACHE:
        return _CACHE[key]
    try:
        manifest = _check_manifest(json.loads(mpath.read_text()), mpath)
    except FileNotFoundError:
        raise LibraryError(f"{mpath}: motion library manifest not found") from None
    except json.JSONDecodeError as exc:
        raise LibraryError(f"{mpath}: not valid JSON ({exc})") from None
    try:
        t = pq.read_table(fpath, columns=["clip", "frame", "root", "dirs"])
    except (OSError, pa.ArrowInvalid, KeyError) as exc:
        raise LibraryError(f"{fpath}: unreadable motion library frames ({type(exc).__name__}: {exc})") from None
    clip = t.column("clip").to_numpy().astype(np.int32)
    frame = t.column("frame").to_numpy().astype(np.int32)
    root = np.asarray(t.column("root").combine_chunks().flatten().to_numpy(), np.float32).reshape(-1, 4)
    dirs = np.asarray(t.column("dirs").combine_chunks().flatten().to_numpy(), np.float32).reshape(-1, N_BONES, 3)
    counts = np.bincount(clip, minlength=len(manifest["clips"])) if len(clip) else np.zeros(len(manifest["clips"]), int)
    if np.any(np.diff(clip) < 0) or len(counts) != len(manifest["clips"]):
        raise LibraryError(f"{fpath}: field 'clip' must run over the manifest's clips in order")
    for i, c in enumerate(manifest["clips"]):
        if int(counts[i]) != int(c["frames"]):
            raise LibraryError(f"{fpath}: clip {c['id']}: {int(counts[i])} frame rows, the manifest says {c['frames']}")
    lib = Library(folder=folder, manifest=manifest, clip=clip, frame=frame, root=root, dirs=dirs)
    _CACHE[key] = lib
    return lib


def check_writable(folder: Path) -> None:
    """Refuse a folder holding files silpose did not write (only a library's own files may be there)."""
    if not folder.exists():
        return
    if not folder.is_dir():
        raise LibraryError(f"{folder}: not a folder")
    foreign = sorted(p.name for p in folder.iterdir()
                     if p.name not in LIBRARY_FILES and not p.match(TMP_GLOB))  # a killed write's leftovers are silpose's
    if foreign:
        raise LibraryError(f"{folder}: holds files silpose did not write ({', '.join(foreign[:3])}"
                           f"{' ...' if len(foreign) > 3 else ''}); give an empty or new folder")
    if (folder / MANIFEST_NAME).exists():
        try:
            _check_manifest(json.loads((folder / MANIFEST_NAME).read_text()), folder / MANIFEST_NAME)
        except json.JSONDecodeError:
            raise LibraryError(f"{folder / MANIFEST_NAME}: not a silpose motion library manifest") from None
    for p in folder.glob(TMP_GLOB):  # only in a folder that is silpose's
        p.unlink(missing_ok=True)


def write_library(folder: str | Path, clips: list[dict], arrays: list[dict], fps: float = DEFAULT_FPS,
                  acknowledgement: str = "") -> Path:
    """Write a library (module docstring): each file atomically (temporary name, then rename), the
    frames first and the manifest last; an interrupted write between the two is caught by
    :func:`load_library` (frame rows that do not match the manifest).

    Args:
        clips: manifest rows (without ``frames``/``lengths``/``extent_m``, filled here).
        arrays: per clip ``frame`` (F,) BVH frame numbers and :func:`derive_clip`'s dict.
    Raises:
        LibraryError: ``folder`` holds files silpose did not write.
    """
    folder = Path(folder)
    check_writable(folder)
    rows = []
    for c, a in zip(clips, arrays):
        rows.append({**c, "frames": int(len(a["frame"])), "lengths": [round(float(v), 5) for v in a["lengths"]],
                     "extent_m": round(float(a["extent_m"]), 4)})
    clip_col = np.concatenate([np.full(len(a["frame"]), i, np.int32) for i, a in enumerate(arrays)]) if arrays else np.zeros(0, np.int32)
    frame_col = np.concatenate([np.asarray(a["frame"], np.int32) for a in arrays]) if arrays else np.zeros(0, np.int32)
    root = np.concatenate([np.asarray(a["root"], np.float32) for a in arrays]) if arrays else np.zeros((0, 4), np.float32)
    dirs = np.concatenate([np.asarray(a["dirs"], np.float32) for a in arrays]) if arrays else np.zeros((0, N_BONES, 3), np.float32)
    table = pa.table({
        "clip": pa.array(clip_col), "frame": pa.array(frame_col),
        "root": pa.FixedSizeListArray.from_arrays(pa.array(root.reshape(-1)), 4),
        "dirs": pa.FixedSizeListArray.from_arrays(pa.array(dirs.reshape(-1)), N_BONES * 3),
    })
    manifest = {"format": FORMAT, "version": VERSION, "acknowledgement": acknowledgement, "fps": fps,
                "roles": list(ROLES), "parents": list(PARENTS), "clips": rows}
    folder.mkdir(parents=True, exist_ok=True)
    with atomic_path(folder / FRAMES_NAME) as tmp:
        pq.write_table(table, tmp, compression="zstd", compression_level=19)
    write_json_atomic(folder / MANIFEST_NAME, manifest)
    return folder


# ------------------------------------------------------------------------------------------ worker

#: The joint map of a library frame's role positions (:func:`retarget.clip_points` reads it).
LIBRARY_MAP = ResolvedMap(
    name="library", index={r: _IDX[r] for r in REQUIRED_ROLES + OPTIONAL_ROLES}, spine_chain=CHAIN, head_tail=False)


class LibraryClip:
    """One library clip in a render worker, with the interface :class:`bvh_motion.BvhMotion` draws
    from: ``name``, ``weight``, ``used`` (its BVH frame numbers) and :meth:`points`."""

    def __init__(self, lib: Library, c: int, weight: float):
        r = lib.rows(c)
        self.name = str(lib.clips[c]["id"])
        self.weight = float(weight)
        self.used = np.asarray(lib.frame[r], np.int64)
        self._pos = lib.positions(c)
        missing = [ROLES.index(k) for k in OPTIONAL_ROLES if not np.all(np.isfinite(self._pos[:, ROLES.index(k)]))]
        index = {k: (-1 if _IDX[k] in missing else v) for k, v in LIBRARY_MAP.index.items()}
        self.jmap = ResolvedMap(name="library", index=index, spine_chain=CHAIN, head_tail=False)

    def points(self, frame: int, mirror: bool) -> dict[str, np.ndarray]:
        """Role positions of BVH frame ``frame`` (metres; :func:`retarget.clip_points`)."""
        k = int(np.searchsorted(self.used, frame))
        if k >= len(self.used) or self.used[k] != frame:
            raise KeyError(f"clip {self.name}: frame {frame} is not in the library")
        P = np.nan_to_num(self._pos[k])
        return clip_points(P, P, self.jmap, mirror)
