"""The Ray executor produces the same shards as the local spawn pool (real renderer, local Ray)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from silpose.datagen.config import load_config
from silpose.datagen.pipeline import generate
from silpose.datagen.testing import tiny_config_toml
from silpose.shared.dataset import load_split

TINY = tiny_config_toml(seed=11)


@pytest.mark.ray
@pytest.mark.blender
def test_ray_matches_local_pool(tmp_path, local_ray):
    cfg_path = tmp_path / "tiny.toml"
    cfg_path.write_text(TINY)
    cfg = load_config(cfg_path)
    via_ray = generate(cfg, tmp_path / "ray", executor="ray", workers=2, progress=False)
    local = generate(cfg, tmp_path / "local", executor="local", workers=1, progress=False)
    assert "bpy" not in sys.modules
    assert via_ray["timing"]["executor"] == "ray"
    assert [s["sha256"] for s in via_ray["shards"]] == [s["sha256"] for s in local["shards"]]
    for split in ("train", "test"):
        a = load_split(tmp_path / "ray", split, with_masks=True)
        b = load_split(tmp_path / "local", split, with_masks=True)
        for name in ("sample_id", "joints", "contours", "masks", "centroid", "scale"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
