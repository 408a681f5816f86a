"""Config presets and validation: every bad value gives a one-line error naming the file and field."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from silpose.datagen.config import ConfigError, available_presets, configs_dir, load_config
from silpose.datagen.pipeline import plan_shards
from silpose.shared.camera import Camera, Rig, default_rig, ring_rig

BASE = """name = "tiny"
seed = 7
renderer = "raster"
blender_engine = "workbench"
shard_size = 4
n_points = 200
max_redraws = 50
[splits]
train = 8
test = 4
"""


def write(tmp_path, text, name="cfg.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_presets_have_the_documented_sizes():
    assert {"smoke", "default", "paper"} <= set(available_presets())
    sizes = {p: load_config(p).splits for p in ("smoke", "default", "paper")}
    assert sizes["smoke"]["train"] <= 64 and sizes["smoke"]["test"] <= 16
    assert sizes["default"] == {"train": 2000, "test": 500}
    assert sizes["paper"] == {"train": 20000, "test": 3000}
    for p in ("smoke", "default", "paper"):
        raw = tomllib.loads((configs_dir() / f"{p}.toml").read_text())
        assert raw["name"] == p


def test_user_toml_and_worker_config(tmp_path):
    cfg = load_config(write(tmp_path, BASE))
    assert (cfg.name, cfg.seed, cfg.shard_size, cfg.splits) == ("tiny", 7, 4, {"train": 8, "test": 4})
    w = cfg.worker_config()
    assert set(w) == {"seed", "renderer", "blender_engine", "rig", "n_points", "max_redraws"}
    assert w["rig"] == default_rig().to_dict()
    tasks = plan_shards(cfg)
    assert [t.file for t in tasks] == [
        "train-00000-of-00002.parquet", "train-00001-of-00002.parquet", "test-00000-of-00001.parquet"]
    assert [t.indices for t in tasks] == [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 2, 3)]
    assert load_config(write(tmp_path, BASE), seed=9, renderer="blender").seed == 9


def test_train_table_is_stored_but_changes_no_sample(tmp_path):
    """``[train]`` reaches the dataset's config (where ``silpose train`` reads it) and nothing a sample depends on."""
    plain = load_config(write(tmp_path, BASE))
    trained = load_config(write(tmp_path, BASE + "[train]\ncomponents = 25\nfits = 5\nstructure_weight = 10\n",
                                "trained.toml"))
    table = {"components": 25, "fits": 5, "structure_weight": 10.0}
    assert trained.train == table and plain.train is None and isinstance(trained.train["structure_weight"], float)
    assert trained.to_dict()["train"] == table and "train" not in plain.to_dict()
    assert trained.data_config() == plain.data_config()
    assert trained.worker_config() == plain.worker_config()


def test_uneven_last_shard(tmp_path):
    cfg = load_config(write(tmp_path, BASE.replace("train = 8", "train = 10")))
    tasks = [t for t in plan_shards(cfg) if t.split == "train"]
    assert [len(t.indices) for t in tasks] == [4, 4, 2]
    assert sorted(i for t in tasks for i in t.indices) == list(range(10))


@pytest.mark.parametrize(
    "old,new,field",
    [
        ('renderer = "raster"', 'renderer = "eevee"', "'renderer' must be one of raster, blender"),
        ('blender_engine = "workbench"', 'blender_engine = "eevee"', "'blender_engine'"),
        ("shard_size = 4", "shard_size = 0", "'shard_size' must be in [1,"),
        ("seed = 7", "seed = -1", "'seed' must be in [0,"),
        ("seed = 7", 'seed = "x"', "'seed' must be an integer"),
        ("n_points = 200", "n_points = 2.5", "'n_points' must be an integer"),
        ('name = "tiny"', 'name = "a/b"', "'name'"),
        ("train = 8", "train = -3", "'train' must be in [0,"),
        ("train = 8", "trian = 8", "'splits.trian': unknown split"),
        ("max_redraws = 50", "max_redraws = 50\ncolour = 1", "unknown field(s) colour"),
        ("shard_size = 4\n", "", "'shard_size' missing"),
        ("test = 4\n", "test = 4\n[train]\nfits = 0\n", "'fits' must be in [1,"),
        ("test = 4\n", "test = 4\n[train]\ncomponents = 2.5\n", "'components' must be an integer"),
        ("test = 4\n", "test = 4\n[train]\nepochs = 3\n",
         "'train.epochs': unknown; known: components, latent, fits, structure_weight"),
        ("test = 4\n", "test = 4\n[train]\nstructure_weight = 0\n", "'structure_weight' must be a number > 0"),
        ("test = 4\n", "test = 4\n[train]\nstructure_weight = \"10\"\n", "'structure_weight' must be a number > 0"),
        ("max_redraws = 50", "max_redraws = 50\ntrain = 3", "'train' must be a table"),
    ],
)
def test_bad_values_name_file_and_field(tmp_path, old, new, field):
    assert old in BASE
    path = write(tmp_path, BASE.replace(old, new, 1))
    with pytest.raises(ConfigError) as err:
        load_config(path)
    msg = str(err.value)
    assert msg.startswith(str(path)) and field in msg and "\n" not in msg


def test_unknown_preset_lists_the_available_ones():
    with pytest.raises(ConfigError, match=r"nope: unknown preset; available presets: .*default.*paper.*smoke"):
        load_config("nope")
    with pytest.raises(ConfigError, match="config file not found"):
        load_config("missing/dir/x.toml")


def test_invalid_toml(tmp_path):
    path = write(tmp_path, "name = \n")
    with pytest.raises(ConfigError, match="not valid TOML") as err:
        load_config(path)
    assert str(path) in str(err.value)


def test_rig_file_relative_to_the_toml(tmp_path):
    rig = ring_rig(n_cameras=3, azimuth_step_deg=60.0, focal_px=400.0)
    (tmp_path / "rigs").mkdir()
    (tmp_path / "rigs" / "three.json").write_text(rig.to_json())
    cfg = load_config(write(tmp_path, BASE + '[rig]\nfile = "rigs/three.json"\n'))
    assert len(cfg.rig) == 3
    np.testing.assert_allclose(cfg.rig[2].R, rig[2].R)
    assert cfg.worker_config()["rig"] == {**rig.to_dict(), "source": str(tmp_path / "rigs" / "three.json")}


def test_rig_that_does_not_see_the_workspace_is_blamed_on_the_rig_file(tmp_path):
    narrow = ring_rig(focal_px=2000.0)  # a telephoto lens sees only the middle of the floor
    (tmp_path / "narrow.json").write_text(narrow.to_json())
    path = write(tmp_path, BASE + '[rig]\nfile = "narrow.json"\n')
    with pytest.raises(ConfigError) as err:
        load_config(path)
    msg = str(err.value)
    assert msg.startswith(f"{tmp_path / 'narrow.json'}: camera 'cam0' does not see the workspace corner"), msg
    assert "silpose rig show" in msg and "\n" not in msg


def test_workspace_table_overrides_the_rig_and_moves_the_walkers(tmp_path):
    path = write(tmp_path, BASE + "[workspace]\ncenter = [0.25, -0.5]\nsize = [1.0, 2.0]\n")
    cfg = load_config(path)
    assert cfg.rig.workspace.bounds == ((-0.25, 0.75), (-1.5, 0.5))
    assert cfg.to_dict()["workspace"] == {"center": [0.25, -0.5], "size": [1.0, 2.0]}
    assert cfg.worker_config()["rig"]["workspace"] == {"center": [0.25, -0.5], "size": [1.0, 2.0]}
    assert "workspace" not in load_config(write(tmp_path, BASE, name="plain.toml")).to_dict()  # unchanged dict
    with pytest.raises(ConfigError) as err:  # a workspace the default rig cannot see
        load_config(write(tmp_path, BASE + "[workspace]\nsize = [9.0, 9.0]\n", name="big.toml"))
    assert str(err.value).startswith(f"{tmp_path / 'big.toml'}: field 'workspace': rig: camera 'cam0' does not see")


@pytest.mark.parametrize(
    "rig,field",
    [
        ('[rig]\npreset = "other"\n', "'rig.preset' must be 'default'"),
        ('[rig]\nfile = "absent.json"\n', "field 'rig.file'"),
        ('[rig]\npreset = "default"\nfile = "x.json"\n', "exactly one of preset, file"),
        ('[rig]\nopencv = ["cam0.yml"]\n', "field 'rig.opencv': calibration files are converted once with `silpose rig import"),
        ('[rig]\nfile = "x.json"\nunit = 0.001\n', "field 'rig.unit'"),
        ('[workspace]\ncenter = [0, 0]\n', "field 'workspace.size' missing"),
        ('[workspace]\nsize = [1, 2, 3]\n', "field 'workspace.size' must be two numbers"),
        ('[workspace]\nsize = [1, -2]\n', "workspace field size: must be positive"),
        ('[workspace]\nsize = [1, 2]\ncentre = [0, 0]\n', "field 'workspace.centre': unknown"),
        ('workspace = 3\n', "field 'workspace' must be a table"),
    ],
)
def test_bad_rig_tables(tmp_path, rig, field):
    path = write(tmp_path, rig + BASE if rig.startswith("workspace =") else BASE + rig)
    with pytest.raises(ConfigError, match=field.replace("(", r"\(").replace(".", r"\.")) as err:
        load_config(path)
    assert str(err.value).startswith(str(path))


def test_rig_in_the_wrong_unit_says_so(tmp_path):
    """A rig whose translations were left in millimetres puts the cameras 1000x too far."""
    ref = default_rig()
    far = Rig(tuple(Camera(c.name, c.K, c.R, c.t * 1000.0, c.width, c.height) for c in ref))
    (tmp_path / "mm.json").write_text(far.to_json())
    with pytest.raises(ConfigError, match=r"camera 'cam0' shows a 1.75 m person at the workspace centre only 0.\d+ px tall"):
        load_config(write(tmp_path, BASE + '[rig]\nfile = "mm.json"\n'))
