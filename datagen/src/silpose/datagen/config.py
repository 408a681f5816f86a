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
    preset = "default"          # or file = "rig.json", or opencv = ["cam0.yml", ...], unit = 0.001

Relative rig paths are resolved against the TOML file's folder.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from silpose.shared.camera import Rig, RigError, default_rig, load_rig

from .blender_scene import ENGINES
from .renderers import MASK_RENDERERS

SPLITS = ("train", "test")
#: Height (m) up to which the workspace corners must be seen: a tall person's head top.
WORKSPACE_CHECK_HEIGHT = 2.0
_KEYS = {"name", "seed", "renderer", "blender_engine", "shard_size", "n_points", "max_redraws", "splits", "rig", "frames"}
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

    def to_dict(self) -> dict:
        """JSON-serialisable config, as stored in the dataset metadata and manifest."""
        return {
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

    def worker_config(self) -> dict:
        """The dict ``render_samples`` reads (seed, renderer, blender_engine, rig, n_points, max_redraws)."""
        return {
            "seed": self.seed,
            "renderer": self.renderer,
            "blender_engine": self.blender_engine,
            "rig": self.rig.to_dict(),
            "n_points": self.n_points,
            "max_redraws": self.max_redraws,
        }

    def data_config(self) -> dict:
        """The part of the config the sample content depends on (not shard size or name)."""
        d = self.to_dict()
        for k in ("name", "shard_size", "splits", "rig_spec"):
            d.pop(k)
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
        raw = tomllib.loads(path.read_text())
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
    rig = build_rig(rig_spec, Path(source).parent if Path(source).suffix == ".toml" else Path.cwd(), src)
    return GenConfig(name, seed, renderer, engine, shard_size, n_points, max_redraws, splits,
                     _portable_rig_spec(rig_spec), rig, source)


def _portable_rig_spec(spec) -> dict:
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in dict(spec).items()}


def build_rig(spec, base: Path, src: str) -> Rig:
    """The rig described by a ``[rig]`` table; checks it sees the workspace up to head height."""
    if not isinstance(spec, dict):
        raise ConfigError(f"{src}: field 'rig' must be a table")
    keys = set(spec) - {"unit"}
    if len(keys) != 1 or not keys <= {"preset", "file", "opencv"}:
        raise ConfigError(f"{src}: field 'rig' needs exactly one of preset, file, opencv (got {sorted(spec)})")
    unit = spec.get("unit", 1.0)
    if not isinstance(unit, (int, float)) or isinstance(unit, bool) or not unit > 0:
        raise ConfigError(f"{src}: field 'rig.unit' must be a positive number, got {unit!r}")
    try:
        if "preset" in spec:
            if spec["preset"] != "default":
                raise ConfigError(f"{src}: field 'rig.preset' must be 'default', got {spec['preset']!r}")
            rig = default_rig()
        elif "file" in spec:
            rig = load_rig(_path(spec["file"], base, src, "rig.file"), unit=float(unit))
        else:
            files = spec["opencv"]
            if isinstance(files, str):
                files = [files]
            if not isinstance(files, list) or not files:
                raise ConfigError(f"{src}: field 'rig.opencv' must be a list of calibration files")
            rig = load_rig([_path(f, base, src, "rig.opencv") for f in files], unit=float(unit))
        rig.image_size  # all views share one image size (the mask tensor is K x H x W)
    except RigError as exc:
        raise ConfigError(f"{src}: field 'rig': {exc}") from None
    check_rig(rig, src)
    return rig


#: Smallest image height (px) of a 1.75 m person at the workspace centre that still gives a contour.
MIN_PERSON_PX = 20.0


def check_rig(rig: Rig, src: str) -> None:
    """Raise ConfigError unless every camera sees the workspace from the floor to head height
    and shows a 1.75 m person at the centre at least ``MIN_PERSON_PX`` pixels tall (a wrong
    ``unit`` typically puts the cameras 1000 times too far or too close)."""
    try:
        rig.check_sees_workspace(height=WORKSPACE_CHECK_HEIGHT)
    except RigError as exc:
        raise ConfigError(f"{src}: field 'rig': {exc}") from None
    for cam in rig:
        feet, head = cam.project(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.75]]))
        size = float(np.linalg.norm(head - feet))
        if size < MIN_PERSON_PX:
            raise ConfigError(
                f"{src}: field 'rig': camera {cam.name!r} shows a 1.75 m person only {size:.2f} px tall "
                f"(need {MIN_PERSON_PX:.0f}); check the distance unit (rig.unit)"
            )


def _path(value, base: Path, src: str, what: str) -> Path:
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{src}: field {what!r} must be a file path")
    p = Path(value).expanduser()
    return p if p.is_absolute() else base / p
