"""The ``[motion]`` section of a generation config: where poses come from (validation only, no bpy).

::

    [motion]
    source = "bvh"                 # "procedural" (default: the walk cycle) | "bvh" (motion-capture clips)
    bvh = ["clips/*.bvh"]          # globs relative to the config file; every match is a clip (.bvh; also
                                   # .fbx/.glb/.gltf, .trc/.c3d of joint keypoints, and .amc with its .asf beside it:
                                   # these in metres, scale 1)
    scale = 0.056444               # metres per BVH unit (defaults for every clip; see below)
    joint_map = "auto"             # "auto" | "cmu" | "mixamo" | "hip-knee" | "bandai" | "cc-base" | "daz" | "mocapnet" | "cmu-asf" | "keypoints" | "my_map.toml"
    stride = 1                     # use every stride-th frame
    frames = [0, -1]               # first and last frame used (inclusive; negative counts from the end)
    mirror = false                 # draw a left/right mirrored copy half of the time (augmentation)
    weight = 1.0                   # per-frame weight of a clip (below)
    licence = "..."                # licence / source notes, recorded in the dataset card
    note = "..."
    [[motion.clip]]                # per-clip settings; override the defaults above
    file = "clips/49_18.bvh"       # a path or glob (a clip both here and in bvh takes these settings)
    weight = 3.0
    frames = [120, -1]
    licence = "CMU Graphics Lab Motion Capture Database: free for all uses"

Units (``scale``, metres per BVH unit): 1.0 for files in metres, 0.01 for centimetres (Mixamo,
LAFAN1, Bandai Namco), and 0.056444 for the widely used CMU BVH conversions, whose unit is the CMU
ASF length unit of 1/0.45 inch (0.0254 / 0.45 = 0.056444 m). Retargeting uses only the clip's
bone *directions*, so a wrong scale does not change the poses; it is recorded in the card with
each clip's measured stature (a check that the unit is right).

Sampling: every used frame of clip c has weight ``weight_c``, so a clip is drawn with probability
``weight_c * n_used_c / sum_k(weight_k * n_used_k)`` and its used frames uniformly; with all
weights 1 every used frame is equally likely. A clip matched by several entries is one clip.
CMU conversions start with a calibration pose in frame 0: use ``frames = [1, -1]``.

The motion library instead (no BVH import at generation time; :mod:`.library`, :mod:`.mix`)::

    [motion]
    source = "library"
    library = "bundled"            # or a folder written by `silpose motions import`
    groups = ["walk", "dance"]     # activity groups used (default: every group of the library)
    weights = { walk = 1.0, dance = 2.0 }   # per-group share of the library draws (default 1 each)
    procedural_walk = 0.2          # share of samples posed by the procedural walk instead
    mirror = true
    part_mix = 0.3                 # share of training library frames whose legs come from another frame
    limb_swing = 0.3               # share of training library frames whose arms and legs are swung
    limb_swing_deg = 90            # largest swing, degrees (default 90)

``part_mix`` (augmentation, training samples only; default 0): the hips and legs of that share of
the training split's library frames come from a second training frame, turned about the vertical
to the first frame's hip line (:func:`.retarget.combine_legs`), so the training poses hold
upper- and lower-body combinations that no clip has.

``limb_swing`` (augmentation, training samples only; default 0): each arm of that share of the
training split's library frames is turned about its shoulder and each leg about its hip, as a rigid
chain, by an angle uniform in [0, ``limb_swing_deg``] about a uniformly random axis
(:func:`.retarget.swing_limbs`): an arm raised overhead, a leg lifted to the side, poses between the
clips' own.
"""

from __future__ import annotations

import glob
from dataclasses import dataclass, field
from pathlib import Path

from .joint_maps import BUILTIN_MAPS, JointMapError, load_map_file

SOURCES = ("procedural", "bvh", "library")
#: Metres per unit of the CMU BVH conversions (1/0.45 inch).
CMU_SCALE = 0.0254 / 0.45
_KEYS = {"source", "bvh", "scale", "joint_map", "stride", "frames", "mirror", "weight", "licence", "note", "clip"}
_LIBRARY_KEYS = {"source", "library", "groups", "weights", "procedural_walk", "mirror", "part_mix", "limb_swing",
                 "limb_swing_deg"}
#: The largest ``limb_swing_deg`` (degrees): a half turn.
MAX_SWING_DEG = 180.0
_CLIP_KEYS = {"file", "scale", "joint_map", "stride", "frames", "weight", "licence", "note"}


class MotionConfigError(ValueError):
    """An invalid ``[motion]`` section; the message names the file and the field."""


@dataclass(frozen=True)
class ClipSpec:
    """One clip as configured (before import).

    Attributes:
        path: the BVH file (absolute).
        file: the path as written relative to the config file (recorded in the dataset).
        scale: metres per BVH unit. joint_map: map spec (``"auto"``, built-in name, or TOML path).
        stride, frames: every ``stride``-th frame of ``frames = (first, last)`` (inclusive, negative
            from the end). weight: per-frame weight. licence, note: free text for the card.
    """

    path: Path
    file: str
    scale: float
    joint_map: str
    stride: int
    frames: tuple[int, int]
    weight: float
    licence: str
    note: str


@dataclass(frozen=True)
class MotionConfig:
    """A validated ``[motion]`` section: ``source`` and, for ``"bvh"``, the clips in file order."""

    source: str = "procedural"
    clips: tuple[ClipSpec, ...] = ()
    mirror: bool = False
    base: Path = field(default=Path("."), repr=False)
    library: str = "bundled"
    groups: tuple[str, ...] = ()
    weights: dict = field(default_factory=dict)
    walk_share: float = 0.0
    part_mix: float = 0.0
    limb_swing: float = 0.0
    limb_swing_deg: float = 90.0

    @property
    def is_bvh(self) -> bool:
        return self.source == "bvh"

    @property
    def uses_clips(self) -> bool:
        """Poses come from motion-capture clips (BVH files or the motion library)."""
        return self.source in ("bvh", "library")


def _library_from_dict(raw: dict, base: Path, msrc: str) -> MotionConfig:
    """``source = "library"``: the motion library (:mod:`.mix`), mixed with the procedural walk."""
    unknown = sorted(set(raw) - _LIBRARY_KEYS)
    if unknown:
        raise MotionConfigError(f"{msrc}: field {unknown[0]!r} is not used with source = \"library\"; "
                                f"known: {', '.join(sorted(_LIBRARY_KEYS))}")
    lib = _str(raw, "library", msrc, "bundled")
    if lib != "bundled":
        p = Path(lib).expanduser()
        lib = str(p if p.is_absolute() else (base / p).resolve())
    groups = raw.get("groups", [])
    if not isinstance(groups, list) or not all(isinstance(g, str) and g for g in groups):
        raise MotionConfigError(f"{msrc}: field 'groups' must be a list of activity group names, got {groups!r}")
    weights = raw.get("weights", {})
    if not isinstance(weights, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0 for v in weights.values()):
        raise MotionConfigError(f"{msrc}: field 'weights' must be a table of group = weight >= 0, got {weights!r}")
    share, part_mix, swing = (_share(raw, key, msrc) for key in ("procedural_walk", "part_mix", "limb_swing"))
    swing_deg = raw.get("limb_swing_deg", 90.0)
    if (not isinstance(swing_deg, (int, float)) or isinstance(swing_deg, bool)
            or not 0.0 < swing_deg <= MAX_SWING_DEG):
        raise MotionConfigError(f"{msrc}: field 'limb_swing_deg' must be a number of degrees in (0, "
                                f"{MAX_SWING_DEG:g}], got {swing_deg!r}")
    mirror = raw.get("mirror", False)
    if not isinstance(mirror, bool):
        raise MotionConfigError(f"{msrc}: field 'mirror' must be true or false, got {mirror!r}")
    return MotionConfig(source="library", mirror=mirror, base=base, library=lib, groups=tuple(groups),
                        weights={str(k): float(v) for k, v in weights.items()}, walk_share=share,
                        part_mix=part_mix, limb_swing=swing, limb_swing_deg=float(swing_deg))


def _share(raw: dict, key: str, msrc: str) -> float:
    """``raw[key]`` (default 0) checked to be a number in [0, 1]."""
    value = raw.get(key, 0.0)
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not 0.0 <= value <= 1.0:
        raise MotionConfigError(f"{msrc}: field {key!r} must be a number in [0, 1], got {value!r}")
    return float(value)


def _num(d: dict, key: str, src: str, default, lo: float, kind=float):
    v = d.get(key, default)
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) if kind is float else isinstance(v, int) and not isinstance(v, bool)
    if not ok or not v > lo:
        raise MotionConfigError(f"{src}: field {key!r} must be {'a number' if kind is float else 'an integer'} > {lo}, got {v!r}")
    return kind(v)


def _str(d: dict, key: str, src: str, default: str) -> str:
    v = d.get(key, default)
    if not isinstance(v, str):
        raise MotionConfigError(f"{src}: field {key!r} must be a string, got {v!r}")
    return v


def _frames(d: dict, key: str, src: str, default) -> tuple[int, int]:
    v = d.get(key, default)
    if (not isinstance(v, (list, tuple)) or len(v) != 2
            or not all(isinstance(x, int) and not isinstance(x, bool) for x in v)):
        raise MotionConfigError(f"{src}: field {key!r} must be [first, last] frame numbers (integers), got {v!r}")
    return int(v[0]), int(v[1])


def _map(d: dict, key: str, src: str, default: str, base: Path) -> str:
    v = _str(d, key, src, default)
    if v == "auto" or v in BUILTIN_MAPS:
        return v
    p = Path(v).expanduser()
    p = p if p.is_absolute() else base / p
    try:
        load_map_file(p)
    except JointMapError as exc:
        raise MotionConfigError(f"{src}: field {key!r}: {exc}") from None
    return str(p)


def _glob(pattern, base: Path, src: str, what: str) -> list[Path]:
    if not isinstance(pattern, str) or not pattern:
        raise MotionConfigError(f"{src}: field {what!r} must hold file paths or globs, got {pattern!r}")
    p = Path(pattern).expanduser()
    full = p if p.is_absolute() else base / p
    hits = sorted(Path(h) for h in glob.glob(str(full), recursive=True))
    hits = [h for h in hits if h.is_file()]
    if not hits:
        raise MotionConfigError(f"{src}: field {what!r}: {pattern!r} matches no file (relative to {base})")
    return hits


def motion_from_dict(raw, base: Path, src: str) -> MotionConfig:
    """Validate a ``[motion]`` table (module docstring); relative paths are against ``base``."""
    if raw is None:
        return MotionConfig(base=base)
    if not isinstance(raw, dict):
        raise MotionConfigError(f"{src}: field 'motion' must be a table")
    msrc = f"{src}: motion"
    if raw.get("source") == "library":
        return _library_from_dict(raw, base, msrc)
    unknown = sorted(set(raw) - _KEYS)
    if unknown:
        raise MotionConfigError(f"{msrc}: unknown field(s) {', '.join(unknown)}; known: {', '.join(sorted(_KEYS))}")
    source = raw.get("source", "procedural")
    if source not in SOURCES:
        raise MotionConfigError(f"{msrc}: field 'source' must be one of {', '.join(SOURCES)}, got {source!r}")
    if source == "procedural":
        extra = sorted(set(raw) - {"source"})
        if extra:
            raise MotionConfigError(f"{msrc}: field {extra[0]!r} needs source = \"bvh\"")
        return MotionConfig(base=base)
    mirror = raw.get("mirror", False)
    if not isinstance(mirror, bool):
        raise MotionConfigError(f"{msrc}: field 'mirror' must be true or false, got {mirror!r}")
    defaults = {
        "scale": _num(raw, "scale", msrc, 1.0, 0.0), "joint_map": _map(raw, "joint_map", msrc, "auto", base),
        "stride": _num(raw, "stride", msrc, 1, 0, int), "frames": _frames(raw, "frames", msrc, (0, -1)),
        "weight": _num(raw, "weight", msrc, 1.0, 0.0), "licence": _str(raw, "licence", msrc, ""),
        "note": _str(raw, "note", msrc, ""),
    }
    order: list[Path] = []
    settings: dict[Path, dict] = {}
    globs = raw.get("bvh", [])
    if isinstance(globs, str):
        globs = [globs]
    if not isinstance(globs, list):
        raise MotionConfigError(f"{msrc}: field 'bvh' must be a list of file paths or globs")
    for pattern in globs:
        for hit in _glob(pattern, base, msrc, "bvh"):
            if hit not in settings:
                order.append(hit)
                settings[hit] = dict(defaults)
    entries = raw.get("clip", [])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise MotionConfigError(f"{msrc}: field 'clip' must be [[motion.clip]] tables")
    for i, entry in enumerate(entries):
        csrc = f"{msrc}.clip[{i}]"
        unknown = sorted(set(entry) - _CLIP_KEYS)
        if unknown:
            raise MotionConfigError(f"{csrc}: unknown field(s) {', '.join(unknown)}; known: {', '.join(sorted(_CLIP_KEYS))}")
        if "file" not in entry:
            raise MotionConfigError(f"{csrc}: field 'file' missing")
        own = {
            "scale": _num(entry, "scale", csrc, defaults["scale"], 0.0),
            "joint_map": _map(entry, "joint_map", csrc, defaults["joint_map"], base) if "joint_map" in entry else defaults["joint_map"],
            "stride": _num(entry, "stride", csrc, defaults["stride"], 0, int),
            "frames": _frames(entry, "frames", csrc, defaults["frames"]),
            "weight": _num(entry, "weight", csrc, defaults["weight"], 0.0),
            "licence": _str(entry, "licence", csrc, defaults["licence"]), "note": _str(entry, "note", csrc, defaults["note"]),
        }
        for hit in _glob(entry["file"], base, csrc, "file"):
            if hit not in settings:
                order.append(hit)
            settings[hit] = own
    if not order:
        raise MotionConfigError(f"{msrc}: source = \"bvh\" needs clips: field 'bvh' (globs) or [[motion.clip]] entries")
    clips = []
    for path in order:
        s = settings[path]
        try:
            rel = str(path.resolve().relative_to(base.resolve()))
        except ValueError:
            rel = str(path)
        clips.append(ClipSpec(path=path.resolve(), file=rel, **s))
    return MotionConfig(source="bvh", clips=tuple(clips), mirror=mirror, base=base)
