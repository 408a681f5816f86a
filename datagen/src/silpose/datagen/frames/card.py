"""The README.md card of a frames dataset (see :mod:`.generate`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_text_atomic

from ..config import GenConfig
from . import scene as fs
from .config import FramesConfig


def card_text(config: GenConfig, fcfg: FramesConfig, stats: dict) -> str:
    cams = list(config.rig.names)
    W, H = config.rig.image_size
    secs = np.asarray(stats.get("image_seconds", []), float)
    timing = (f"{secs.mean():.2f} s per {W}x{H} image (median {np.median(secs):.2f} s, one render thread per "
              f"worker) over the {secs.size} images rendered by the run that completed the folder"
              if secs.size else "no image rendered by the run that completed the folder")
    props = ", ".join(f"{p['name']} at ({p['boxes'][0][0][0]:.1f}, {p['boxes'][0][0][1]:.1f}) m"
                      for p in fs.place_props(config.rig)) or "none"
    return f"""# silpose frames dataset `{config.name}`

Textured camera frames of a walking person, rendered with Blender Cycles, for the background
subtraction and end-to-end path. Made by `silpose gen-frames {config.name}`.

- **Person frames**: test samples 0..{fcfg.samples - 1} of the `{config.name}` preset (seed
  {config.seed}): frame i shows the subject, gait, heading and position of test sample i of
  `silpose gen {config.name}`. Clothing colours (shirt, trousers, skin, hair, shoes; striped
  shirts sometimes) are drawn per sample from a seed stream separate from the sample's.
- **Background frames**: {fcfg.background} empty-room frames per camera: one clean render of the
  room per camera plus per-frame noise and flicker (below).
- **Truth**: `test-*.parquet` is an ordinary silhouette dataset split `test`
  (`silpose.shared.dataset.load_split(dir, "test")`), with the records of `silpose gen`'s test
  samples (renderer `{config.renderer}`): masks, contours, joints bit-identical. The person in the
  frames is the same posed mesh the truth masks are filled from.
- **Scene**: a {2 * fs.room_half_size(config.rig):.0f} m square room centred on the workspace ({fs.room_centre(config.rig)[0]:.1f}, {fs.room_centre(config.rig)[1]:.1f}) m, {fs.ROOM_HEIGHT} m walls, a floor
  with a procedural noise texture, props ({props}) placed where they never hide the workspace
  from a camera; a sun (elevation {fs.SUN['elevation_deg']:.0f} deg, azimuth {fs.SUN['azimuth_deg']:.0f}
  deg) casts the shadows, a uniform world light of strength {fs.AMBIENT} lights them.
- **Rendering**: Cycles CPU, {fcfg.cycles_samples} samples per pixel, fixed sampling seed,
  denoising {'on (OpenImageDenoise)' if fcfg.denoise else 'off'}, "Standard" view transform, 16-bit
  output; {timing}. Person and empty-room renders share scene, cameras and seed, so room pixels
  the person does not affect have identical clean values.
- **Camera noise** (numpy, seeded per frame): `frame = clip(round(g * clean + e), 0, 255)`,
  `g ~ Uniform(1 - {fcfg.flicker}, 1 + {fcfg.flicker})` per frame (illumination flicker),
  `e ~ Normal(0, {fcfg.noise_sigma}^2)` per pixel and channel. Both kinds of frames get it.

## Layout

```
rig.json                         the camera rig (Rig.to_dict() as JSON)
background/<camera>/00000.png …  {fcfg.background} empty-room frames per camera ({W}x{H} uint8 RGB PNG)
frames/<camera>/00000.png …      {fcfg.samples} frames per camera; file i = row i of the truth split
test-00000-of-*.parquet …        truth (silhouette dataset split "test")
README.md                        this card
.silpose-frames.json             the configuration of the run (checked when resuming)
```

Cameras: {', '.join(cams)}.
"""


def write_frames_card(root: Path, config: GenConfig, fcfg: FramesConfig, stats: dict) -> Path:
    """Write ``root/README.md`` (:func:`card_text`) atomically; returns its path."""
    return write_text_atomic(Path(root) / "README.md", card_text(config, fcfg, stats))
