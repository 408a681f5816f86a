"""Config presets and validation: every bad value gives a one-line error naming the file and field."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from silpose.datagen.config import ConfigError, available_presets, configs_dir, load_config
from silpose.datagen.pipeline import plan_shards
from silpose.shared.camera import default_rig, ring_rig

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
    assert cfg.worker_config()["rig"] == rig.to_dict()


def test_rig_that_does_not_see_the_workspace(tmp_path):
    narrow = ring_rig(focal_px=2000.0)  # a telephoto lens sees only the middle of the floor
    (tmp_path / "narrow.json").write_text(narrow.to_json())
    path = write(tmp_path, BASE + '[rig]\nfile = "narrow.json"\n')
    with pytest.raises(ConfigError) as err:
        load_config(path)
    msg = str(err.value)
    assert msg.startswith(str(path)) and "field 'rig'" in msg and "camera 'cam0'" in msg and "workspace" in msg


@pytest.mark.parametrize(
    "rig,field",
    [
        ('[rig]\npreset = "other"\n', "'rig.preset' must be 'default'"),
        ('[rig]\nfile = "absent.json"\n', "rig file not found"),
        ('[rig]\npreset = "default"\nfile = "x.json"\n', "exactly one of preset, file, opencv"),
        ('[rig]\npreset = "default"\nunit = -1\n', "'rig.unit' must be a positive number"),
    ],
)
def test_bad_rig_tables(tmp_path, rig, field):
    path = write(tmp_path, BASE + rig)
    with pytest.raises(ConfigError, match=field.replace("(", r"\(").replace(".", r"\.")) as err:
        load_config(path)
    assert str(path) in str(err.value)


def test_opencv_rig_in_millimetres(tmp_path):
    """A real user's rig: OpenCV FileStorage YAML files written with cv2 itself, translations in mm."""
    import cv2

    ref = default_rig()
    names = []
    for cam in ref:
        name = f"{cam.name}.yml"
        fs = cv2.FileStorage(str(tmp_path / name), cv2.FILE_STORAGE_WRITE)
        fs.write("camera_matrix", cam.K)
        fs.write("distortion_coefficients", np.zeros((5, 1)))
        fs.write("rvec", cv2.Rodrigues(cam.R)[0])
        fs.write("tvec", (cam.t * 1000.0).reshape(3, 1))
        fs.write("image_width", cam.width)
        fs.write("image_height", cam.height)
        fs.release()
        names.append(name)
    files = ", ".join(f'"{n}"' for n in names)
    cfg = load_config(write(tmp_path, BASE + f"[rig]\nopencv = [{files}]\nunit = 0.001\n"))
    assert len(cfg.rig) == len(ref)
    for got, want in zip(cfg.rig, ref):
        np.testing.assert_allclose(got.K, want.K)
        np.testing.assert_allclose(got.R, want.R, atol=1e-9)
        np.testing.assert_allclose(got.t, want.t, atol=1e-9)
    # the same files read as metres put the cameras 1000x too far: a person is a fraction of a pixel
    with pytest.raises(ConfigError, match=r"field 'rig': camera 'cam0' shows a 1.75 m person only 0.\d+ px tall"):
        load_config(write(tmp_path, BASE + f"[rig]\nopencv = [{files}]\n", name="metres.toml"))
