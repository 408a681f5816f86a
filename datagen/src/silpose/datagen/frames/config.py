"""The ``[frames]`` section of a preset TOML (textured camera frames, ``silpose gen-frames``).

    [frames]
    samples = 8            # person frames: test samples 0..samples-1 (one frame per camera each)
    background = 20        # empty-room frames per camera (noise + flicker of one clean render)
    cycles_samples = 16    # Cycles path-tracing samples per pixel
    denoise = true         # OpenImageDenoise on the Cycles render
    noise_sigma = 2.0      # camera noise, standard deviation in 8-bit levels
    flicker = 0.02         # illumination flicker: per-frame gain uniform in [1 - flicker, 1 + flicker]
    shard_size = 2         # samples per worker task (and per truth Parquet shard)

Every key is optional (defaults above); the rest of the TOML is the ordinary generator config
(:mod:`silpose.datagen.config`), whose seed and rig the frames share.
"""

from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass
from pathlib import Path

from ..config import ConfigError, GenConfig, load_config, resolve

DEFAULTS = {"samples": 8, "background": 20, "cycles_samples": 16, "denoise": True, "noise_sigma": 2.0,
            "flicker": 0.02, "shard_size": 2}


@dataclass(frozen=True)
class FramesConfig:
    """Validated ``[frames]`` values (see the module docstring)."""

    samples: int
    background: int
    cycles_samples: int
    denoise: bool
    noise_sigma: float
    flicker: float
    shard_size: int

    def to_dict(self) -> dict:
        return asdict(self)


def _where(key: str, src: str, overridden: set[str]) -> str:
    """Who gave ``frames.<key>``: the command-line option that overrides it, or the config file."""
    if key in overridden:
        return f"--{key.replace('_', '-')} (overrides {src}'s field 'frames.{key}')"
    return f"{src}: field 'frames.{key}'"


def _int(raw: dict, key: str, src: str, lo: int, hi: int, overridden: set[str]) -> int:
    v = raw[key]
    if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
        raise ConfigError(f"{_where(key, src, overridden)} must be an integer in [{lo}, {hi}], got {v!r}")
    return v


def _float(raw: dict, key: str, src: str, lo: float, hi: float, overridden: set[str]) -> float:
    v = raw[key]
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not lo <= v <= hi:
        raise ConfigError(f"{_where(key, src, overridden)} must be a number in [{lo}, {hi}], got {v!r}")
    return float(v)


def frames_from_dict(section, src: str = "config", **overrides) -> FramesConfig:
    """Validate a ``[frames]`` table (None = all defaults); ``overrides`` (not None) replace keys."""
    if section is None:
        section = {}
    if not isinstance(section, dict):
        raise ConfigError(f"{src}: field 'frames' must be a table")
    unknown = sorted(set(section) - set(DEFAULTS))
    if unknown:
        raise ConfigError(f"{src}: unknown field(s) frames.{', frames.'.join(unknown)}; known: {', '.join(DEFAULTS)}")
    raw = dict(DEFAULTS, **section)
    given = {k: v for k, v in overrides.items() if v is not None}
    raw.update(given)
    over = set(given)
    if not isinstance(raw["denoise"], bool):
        raise ConfigError(f"{_where('denoise', src, over)} must be true or false, got {raw['denoise']!r}")
    return FramesConfig(
        samples=_int(raw, "samples", src, 1, 1_000_000, over),
        background=_int(raw, "background", src, 2, 100_000, over),
        cycles_samples=_int(raw, "cycles_samples", src, 1, 4096, over),
        denoise=raw["denoise"],
        noise_sigma=_float(raw, "noise_sigma", src, 0.0, 64.0, over),
        flicker=_float(raw, "flicker", src, 0.0, 0.5, over),
        shard_size=_int(raw, "shard_size", src, 1, 10_000, over),
    )


def load_frames_config(preset_or_path: str | Path, **overrides) -> tuple[GenConfig, FramesConfig]:
    """The generator config and the ``[frames]`` section of a preset name or TOML file.

    ``overrides`` (``samples``, ``background``, ...) replace ``[frames]`` keys when not None.
    """
    path = resolve(preset_or_path)
    config = load_config(path)
    raw = tomllib.loads(path.read_text())  # already parsed once by load_config: valid TOML
    return config, frames_from_dict(raw.get("frames"), str(path), **overrides)
