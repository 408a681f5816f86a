"""Dataset generation configs: TOML presets in ``configs/`` and users' own TOML files.

Keys (all validated; errors are one line naming the file and the field)::

    name = "smoke"              # dataset name; default output folder data/<name>
    seed = 0                    # dataset seed: sample = f(seed, split, index)
    renderer = "raster"         # "raster" (posed Blender mesh filled by OpenCV) | "blender" (.renderers)
    blender_engine = "workbench"  # "workbench" | "cycles" (renderer = "blender" only)
    shard_size = 32             # samples per Parquet shard
    n_points = 200              # contour points per view
    max_redraws = 50            # redraws allowed for a sample not fully visible in every view
    [splits]
    train = 64
    test = 16
    [rig]
    preset = "default"          # or file = "rig.json" (written by `silpose rig import`)
    [workspace]                 # optional: overrides the rig's workspace (metres, silpose's frame)
    center = [0.0, 0.0]
    size = [3.0, 3.0]
    [motion]                    # optional: poses from motion-capture clips (.motion.config)
    source = "bvh"              # "procedural" (default, the walk cycle) | "bvh"
    bvh = ["clips/*.bvh"]
    [train]                     # optional: how `silpose train` fits this dataset by default
    components = 25             # mixture components M per fit
    latent = 40                 # latent dimensions q
    fits = 5                    # EM fits pooled into one mixture (M x fits components)
    structure_weight = 10.0     # weight w of the joint block in the shape vector (a number > 0)

Relative rig and clip paths are resolved against the TOML file's folder. Walkers are placed uniformly in the
workspace (the rig's, or ``[workspace]``); every camera must see it up to a tall person's head
(``silpose.shared.rig_frame.PERSON_HEIGHT_M``), because every sample needs every view whole. A rig file's
own workspace that some camera misses (``silpose rig import --min-views``: the floor enough cameras see) is
accepted: walkers are then placed on its *placement area*, the largest part of it every camera sees
(``Rig.seen_workspace``; ``GenConfig.placement``, stored as ``config.placement`` in the dataset), while the
dataset keeps the rig's whole workspace, where ``silpose infer --videos`` looks for people. A ``[workspace]``
table is where walkers are placed, so every camera must see it whole. Calibration files of other tools are converted by
``silpose rig import`` first (units, up axis, origin, automatic workspace). A ``[motion] source =
"bvh"`` config must be prepared (:meth:`GenConfig.with_motion`, done by ``generate``: the clips are
imported and checked) before its ``to_dict`` and ``worker_config`` exist; a procedural config's
dicts are exactly those of a config without ``[motion]``.

``[train]`` does not change a sample: it is stored in the dataset's config (``train``), where ``silpose train``
reads it as its defaults (``silpose.app.training``; command-line options win), and a rerun with another
``[train]`` keeps the shards (``silpose.datagen.shards.RESUME_NEUTRAL``).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from silpose.shared.camera import Rig, RigError, default_rig, load_rig
from silpose.shared.rig_frame import PERSON_HEIGHT_M, Workspace

from .blender.scene import ENGINES
from .motion.clips import PreparedMotion, prepare_motion
from .motion.mix import PreparedLibrary, prepare_library
from .motion.config import MotionConfig, MotionConfigError, motion_from_dict
from .renderers import MASK_RENDERERS

SPLITS = ("train", "test")
#: Height (m) up to which the workspace corners must be seen: a tall person's head top.
WORKSPACE_CHECK_HEIGHT = PERSON_HEIGHT_M
_KEYS = {"name", "seed", "renderer", "blender_engine", "shard_size", "n_points", "max_redraws", "splits", "rig",
         "workspace", "frames", "motion", "train"}
#: The ``[train]`` table's fields (each optional): ``silpose train``'s M, q and pooled fits (integers >= 1) and the
#: structure weight w (a number > 0, :data:`TRAIN_FLOAT_KEYS`).
TRAIN_KEYS = ("components", "latent", "fits", "structure_weight")
#: The ``[train]`` fields that are numbers, not counts.
TRAIN_FLOAT_KEYS = ("structure_weight",)
#: Sections read by other commands and ignored here: ``[frames]`` (``silpose gen-frames``, :mod:`.frames.config`).
_OTHER_SECTIONS = {"frames"}


class ConfigError(ValueError):
    """A config file or value is invalid; the message names the file and the field."""


def configs_dir() -> Path:
    """The repository's ``configs/`` folder (presets)."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        if (parent / "configs").is_dir() and (parent / "pyproject.toml").is_file():
            return parent / "configs"
    return Path.cwd() / "configs"


def available_presets() -> list[str]:
    d = configs_dir()
    return sorted(p.stem for p in d.glob("*.toml")) if d.is_dir() else []


@dataclass
class GenConfig:
    """A validated generation config (see the module docstring for the keys)."""

    name: str
    seed: int
    renderer: str
    blender_engine: str
    shard_size: int
    n_points: int
    max_redraws: int
    splits: dict[str, int]
    rig_spec: dict
    rig: Rig = field(repr=False)
    source: str = ""
    workspace_spec: dict | None = None
    placement: Workspace | None = None
    motion: MotionConfig = field(default_factory=MotionConfig, repr=False)
    prepared: PreparedMotion | PreparedLibrary | None = field(default=None, repr=False)
    train: dict | None = None

    def with_motion(self, workers: int | None = None) -> "GenConfig":
        """This config with its motion-capture clips imported and checked (itself if procedural)."""
        if not self.motion.uses_clips or self.prepared is not None:
            return self
        if self.motion.source == "library":
            return replace(self, prepared=prepare_library(self.motion))
        return replace(self, prepared=prepare_motion(self.motion, workers=workers))

    def _prepared(self) -> PreparedMotion | PreparedLibrary | None:
        if self.motion.uses_clips and self.prepared is None:
            raise ValueError(f"{self.source}: [motion] source = {self.motion.source!r}: call with_motion() first (imports the clips)")
        return self.prepared

    def to_dict(self) -> dict:
        """JSON-serialisable config, as stored in the dataset metadata and manifest (``workspace``
        only when the config has a ``[workspace]`` table, ``motion`` only for motion-capture clips)."""
        prepared = self._prepared()
        out = {
            "name": self.name,
            "seed": self.seed,
            "renderer": self.renderer,
            "blender_engine": self.blender_engine,
            "shard_size": self.shard_size,
            "n_points": self.n_points,
            "max_redraws": self.max_redraws,
            "splits": dict(self.splits),
            "rig_spec": dict(self.rig_spec),
        }
        if self.workspace_spec is not None:
            out["workspace"] = dict(self.workspace_spec)
        if self.placement is not None:
            out["placement"] = self.placement.to_dict()
        if prepared is not None:
            out["motion"] = prepared.metadata()
        if self.train is not None:
            out["train"] = dict(self.train)
        return out

    def worker_config(self) -> dict:
        """The dict ``render_samples`` reads (seed, renderer, blender_engine, rig, n_points,
        max_redraws, and ``motion`` for motion-capture clips)."""
        prepared = self._prepared()
        out = {
            "seed": self.seed,
            "renderer": self.renderer,
            "blender_engine": self.blender_engine,
            "rig": self.rig.to_dict(),
            "n_points": self.n_points,
            "max_redraws": self.max_redraws,
        }
        if self.placement is not None:
            out["placement"] = self.placement.to_dict()
        if prepared is not None:
            out["motion"] = prepared.worker()
        return out

    def data_config(self) -> dict:
        """The part of the config the sample content depends on (not shard size or name)."""
        d = self.to_dict()
        for k in ("name", "shard_size", "splits", "rig_spec", "workspace", "train"):
            d.pop(k, None)
        return d


def resolve(preset_or_path: str | Path) -> Path:
    """Path of a preset name (``configs/<name>.toml``) or of a TOML file."""
    text = str(preset_or_path)
    p = Path(text)
    if p.suffix == ".toml" or p.is_file() or "/" in text:
        if not p.is_file():
            raise ConfigError(f"{p}: config file not found")
        return p
    candidate = configs_dir() / f"{text}.toml"
    if not candidate.is_file():
        raise ConfigError(f"{text}: unknown preset; available presets: {', '.join(available_presets()) or 'none'}")
    return candidate


def load_config(preset_or_path: str | Path, **overrides) -> GenConfig:
    """Load and validate a preset name or a TOML file; ``overrides`` replace top-level keys."""
    path = resolve(preset_or_path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8-sig"))  # past a Windows editor's byte-order mark
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
    raw.update({k: v for k, v in overrides.items() if v is not None})
    return config_from_dict(raw, source=str(path))


def _int(raw: dict, key: str, src: str, lo: int, hi: int | None = None) -> int:
    if key not in raw:
        raise ConfigError(f"{src}: field {key!r} missing")
    v = raw[key]
    if not isinstance(v, int) or isinstance(v, bool):
        raise ConfigError(f"{src}: field {key!r} must be an integer, got {v!r}")
    if v < lo or (hi is not None and v > hi):
        raise ConfigError(f"{src}: field {key!r} must be in [{lo}, {hi if hi is not None else 'inf'}], got {v}")
    return v


def _choice(raw: dict, key: str, src: str, choices: tuple[str, ...], default: str | None = None) -> str:
    v = raw.get(key, default)
    if v is None:
        raise ConfigError(f"{src}: field {key!r} missing")
    if v not in choices:
        raise ConfigError(f"{src}: field {key!r} must be one of {', '.join(choices)}, got {v!r}")
    return v


def config_from_dict(raw: dict, source: str = "config") -> GenConfig:
    """Validate a config dict (as read from TOML) into a :class:`GenConfig`."""
    src = source
    raw = {k: v for k, v in raw.items() if k not in _OTHER_SECTIONS}
    unknown = sorted(set(raw) - _KEYS)
    if unknown:
        raise ConfigError(f"{src}: unknown field(s) {', '.join(unknown)}; known: {', '.join(sorted(_KEYS))}")
    name = raw.get("name")
    if not isinstance(name, str) or not name or name in (".", "..") or any(c in name for c in "/\\ "):
        raise ConfigError(f"{src}: field 'name' must be a folder name (not '.' or '..') without spaces or slashes, "
                          f"got {name!r}")
    seed = _int(raw, "seed", src, 0, 2**63 - 1)
    renderer = _choice(raw, "renderer", src, MASK_RENDERERS)
    engine = _choice(raw, "blender_engine", src, ENGINES, default="workbench")
    shard_size = _int(raw, "shard_size", src, 1, 100_000)
    n_points = _int(raw, "n_points", src, 8, 10_000)
    max_redraws = _int(raw, "max_redraws", src, 0, 1_000_000)
    splits_raw = raw.get("splits")
    if not isinstance(splits_raw, dict):
        raise ConfigError(f"{src}: field 'splits' missing (a table with train and test counts)")
    bad = sorted(set(splits_raw) - set(SPLITS))
    if bad:
        raise ConfigError(f"{src}: field 'splits.{bad[0]}': unknown split; known: {', '.join(SPLITS)}")
    splits = {s: _int(splits_raw, s, f"{src}: splits", 0, 10_000_000) for s in SPLITS if s in splits_raw}
    if not splits or sum(splits.values()) == 0:
        raise ConfigError(f"{src}: field 'splits' must ask for at least one sample")
    rig_spec = raw.get("rig", {"preset": "default"})
    base = Path(source).parent if Path(source).suffix == ".toml" else Path.cwd()
    rig = build_rig(rig_spec, base, src)
    workspace_spec = raw.get("workspace")
    if workspace_spec is not None:
        rig = rig.with_workspace(parse_workspace(workspace_spec, src))
    placement = check_rig(rig, src, workspace_from=None if workspace_spec is None else f"{src}: field 'workspace'")
    try:
        motion = motion_from_dict(raw.get("motion"), base, src)
    except MotionConfigError as exc:
        raise ConfigError(str(exc)) from None
    return GenConfig(name, seed, renderer, engine, shard_size, n_points, max_redraws, splits,
                     _portable_rig_spec(rig_spec), rig, source,
                     workspace_spec=None if workspace_spec is None else rig.workspace.to_dict(),
                     placement=None if placement is rig.workspace else placement, motion=motion,
                     train=parse_train(raw["train"], src) if "train" in raw else None)


def parse_train(spec, src: str) -> dict:
    """The ``[train]`` table (module docstring): ``{field: value}`` for the :data:`TRAIN_KEYS` it names (counts
    int >= 1, :data:`TRAIN_FLOAT_KEYS` float > 0)."""
    if not isinstance(spec, dict):
        raise ConfigError(f"{src}: field 'train' must be a table with {', '.join(TRAIN_KEYS)}")
    unknown = sorted(set(spec) - set(TRAIN_KEYS))
    if unknown:
        raise ConfigError(f"{src}: field 'train.{unknown[0]}': unknown; known: {', '.join(TRAIN_KEYS)}")
    out = {}
    for k in TRAIN_KEYS:
        if k not in spec:
            continue
        if k in TRAIN_FLOAT_KEYS:
            v = spec[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (0 < float(v) < float("inf")):
                raise ConfigError(f"{src}: train: field {k!r} must be a number > 0, got {v!r}")
            out[k] = float(v)
        else:
            out[k] = _int(spec, k, f"{src}: train", 1, 100_000)
    return out


def _portable_rig_spec(spec) -> dict:
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in dict(spec).items()}


def parse_workspace(spec, src: str) -> Workspace:
    """The ``[workspace]`` table: ``size = [x, y]`` metres and optional ``center = [x, y]`` metres."""
    if not isinstance(spec, dict):
        raise ConfigError(f"{src}: field 'workspace' must be a table with size = [x, y] and center = [x, y] (metres)")
    unknown = sorted(set(spec) - {"center", "size"})
    if unknown:
        raise ConfigError(f"{src}: field 'workspace.{unknown[0]}': unknown; known: center, size")
    if "size" not in spec:
        raise ConfigError(f"{src}: field 'workspace.size' missing ([x, y] metres)")
    for key in ("center", "size"):
        v = spec.get(key, [0.0, 0.0])
        if not (isinstance(v, list) and len(v) == 2
                and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
            raise ConfigError(f"{src}: field 'workspace.{key}' must be two numbers [x, y] (metres), got {v!r}")
    try:
        return Workspace(spec.get("center", [0.0, 0.0]), spec["size"])
    except ValueError as exc:
        raise ConfigError(f"{src}: {exc}") from None


def build_rig(spec, base: Path, src: str) -> Rig:
    """The rig described by a ``[rig]`` table (``preset = "default"`` or ``file = "rig.json"``).

    Errors about a rig file name that file (``Rig.source``), not the config.
    """
    if not isinstance(spec, dict):
        raise ConfigError(f"{src}: field 'rig' must be a table")
    if "opencv" in spec or "unit" in spec:
        raise ConfigError(
            f"{src}: field 'rig.{'opencv' if 'opencv' in spec else 'unit'}': calibration files are converted "
            "once with `silpose rig import CALIB... --unit mm --out rig.json` (units, up axis, origin, "
            "workspace); then use [rig] file = \"rig.json\""
        )
    if len(spec) != 1 or not set(spec) <= {"preset", "file"}:
        raise ConfigError(f"{src}: field 'rig' needs exactly one of preset, file (got {sorted(spec)})")
    if "preset" in spec:
        if spec["preset"] != "default":
            raise ConfigError(f"{src}: field 'rig.preset' must be 'default', got {spec['preset']!r}")
        return default_rig()
    path = _path(spec["file"], base, src, "rig.file")
    if not path.is_file():
        raise ConfigError(f"{src}: field 'rig.file': {path}: rig file not found")
    try:
        rig = load_rig(path)
        rig.image_size  # all views share one image size (the mask tensor is K x H x W)
    except RigError as exc:
        raise ConfigError(str(exc)) from None
    return rig


#: Smallest image height (px) of a 1.75 m person at the workspace centre that still gives a contour.
MIN_PERSON_PX = 20.0


def check_rig(rig: Rig, src: str, workspace_from: str | None = None) -> Workspace:
    """Where walkers are placed: the rig's workspace when every camera sees it from the floor to head
    height, else (a rig file's own workspace only, module docstring) the largest part of it every camera
    sees (``Rig.seen_workspace``). Raise ConfigError when no camera-seen part exists, when a ``[workspace]``
    table (``workspace_from``) is not seen whole, or when a camera shows a 1.75 m person at the placement
    area's centre less than ``MIN_PERSON_PX`` pixels tall (a wrong unit typically puts the cameras 1000
    times too far or too close).

    Errors name the rig's file (or ``src`` for the built-in rig); ``workspace_from`` (e.g.
    ``"cfg.toml: field 'workspace'"``) prefixes them when the config overrides the workspace.
    """
    prefix = f"{workspace_from}: " if workspace_from else ("" if rig.source else f"{src}: field 'rig': ")
    try:
        rig.check_sees_workspace(height=WORKSPACE_CHECK_HEIGHT)
        placement = rig.workspace
    except RigError as exc:
        placement = None if workspace_from or not rig.source else rig.seen_workspace(WORKSPACE_CHECK_HEIGHT)
        if placement is None:
            hint = "" if workspace_from or not rig.source else "; no part of the workspace is seen by every camera"
            raise ConfigError(f"{prefix}{exc}{hint}") from None
    cx, cy = placement.center
    for cam in rig:
        feet, head = cam.project(np.array([[cx, cy, 0.0], [cx, cy, 1.75]]))
        size = float(np.linalg.norm(head - feet))
        if size < MIN_PERSON_PX:
            raise ConfigError(
                f"{prefix}{rig.where}: camera {cam.name!r} shows a 1.75 m person at the workspace centre only "
                f"{size:.2f} px tall (need {MIN_PERSON_PX:.0f}); check the calibration's unit "
                "(`silpose rig import --unit`)"
            )
    return placement


def _path(value, base: Path, src: str, what: str) -> Path:
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{src}: field {what!r} must be a file path")
    p = Path(value).expanduser()
    return p if p.is_absolute() else base / p
