"""Textured camera frames (``silpose gen-frames``): layout, truth, noise model, person region,
floor shadow, determinism and resume, bad input.

Blender runs only in SPAWNED workers (the generator's pool and a module pool here); functions
given to the pool live in the installed package (``silpose.datagen.frames.worker``). To stay fast
the Blender tests use a 2-camera 160x120 rig (same field of view as the default rig). The people are
posed from the bundled motion library (as the ``motions`` preset; the walk is posed in the eval's frames
tests), so the frames path is checked on motion-capture poses too.
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing as mp
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest

from silpose.datagen.frames.scene import check_props_do_not_occlude, occludes, place_props, room_centre, room_half_size
from silpose.datagen.worker import render_samples
from silpose.shared.camera import Rig, default_rig, ring_rig
from silpose.shared.camera_noise import add_camera_noise, noise_rng
from silpose.shared.rig_frame import Workspace
from silpose.shared.dataset import load_split

TIMEOUT_S = 600
RIG = ring_rig(n_cameras=2, focal_px=235.0, width=160, height=120)
SAMPLES, BACKGROUND, SIGMA, FLICKER = 2, 12, 2.0, 0.02

TOML = f"""name = "tinyframes"
seed = 3
renderer = "raster"
shard_size = 2
n_points = 100
max_redraws = 50
[splits]
test = 4
[rig]
file = "rig.json"
[motion]
source = "library"
[frames]
samples = {SAMPLES}
background = {BACKGROUND}
cycles_samples = 16
denoise = true
noise_sigma = {SIGMA}
flicker = {FLICKER}
shard_size = 1
"""


def _read_rgb(path):
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert img is not None and img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3, path
    return img[..., ::-1]


@pytest.fixture(scope="module")
def cfg_path(tmp_path_factory):
    d = tmp_path_factory.mktemp("cfg")
    (d / "rig.json").write_text(RIG.to_json())
    (d / "tiny.toml").write_text(TOML)
    return d / "tiny.toml"


@pytest.fixture(scope="module")
def configs(cfg_path):
    from silpose.datagen.frames.config import load_frames_config

    return load_frames_config(cfg_path)


@pytest.fixture(scope="module")
def built(configs, tmp_path_factory):
    from silpose.datagen.frames.generate import generate_frames

    out = tmp_path_factory.mktemp("frames") / "ds"
    summary = generate_frames(*configs, out, workers=2, progress=False)
    assert not summary["already_complete"] and summary["tasks_rendered"] == 1 + SAMPLES
    return out


@pytest.fixture(scope="module")
def pool():
    with mp.get_context("spawn").Pool(1) as p:
        yield p


@pytest.fixture(scope="module")
def clean(configs, pool):
    """Clean (noise-free) renders from an independent worker: person frames and empty room."""
    from silpose.datagen.frames.worker import render_frames_task

    config, fcfg = configs
    config = config.with_motion()  # the library's clips (read from the repository, no Blender import)
    wc = dict(config.worker_config(), frames={"cycles_samples": fcfg.cycles_samples, "denoise": fcfg.denoise})
    person = pool.apply_async(render_frames_task, (wc, "test", list(range(SAMPLES)))).get(TIMEOUT_S)
    empty = pool.apply_async(render_frames_task, (wc, "background", [])).get(TIMEOUT_S)
    truth = pool.apply_async(render_samples, (config.worker_config(), "test", list(range(SAMPLES)))).get(TIMEOUT_S)
    print(f"Cycles seconds per 160x120 image: {np.mean(person['image_seconds']):.2f}")
    return {"frames": person["frames"], "records": person["records"], "empty": empty["empty"], "truth": truth}


def test_pytest_process_never_imported_bpy():
    code = ("import sys\nimport silpose.datagen.frames.generate, silpose.datagen.frames.cli, silpose.datagen.frames.worker\n"
            "import silpose.datagen.frames.scene, silpose.datagen.frames.render, silpose.datagen.frames.card\n"
            "import silpose.datagen.renderers, silpose.shared.camera_noise\n"
            "assert 'bpy' not in sys.modules, 'bpy imported'\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "bpy" not in sys.modules


def test_props_never_hide_the_workspace():
    for rig in (default_rig(), RIG):
        props = place_props(rig)
        assert [p["name"] for p in props] == ["box", "table"]
        check_props_do_not_occlude(rig, props)
    # a lab calibrated with its origin in a room corner: the room and the props go where people walk
    far = Rig(tuple(dataclasses.replace(c, t=c.t - c.R @ np.array([12.0, 30.0, 0.0])) for c in default_rig()),
              workspace=Workspace(center=np.array([12.0, 30.0])))
    assert room_half_size(far) == pytest.approx(room_half_size(default_rig()))
    np.testing.assert_allclose(room_centre(far), [12.0, 30.0])
    props = place_props(far)
    assert [p["name"] for p in props] == ["box", "table"]
    for p, q in zip(props, place_props(default_rig())):  # the same layout, moved with the rig
        np.testing.assert_allclose(p["boxes"][0][0], q["boxes"][0][0] + np.array([12.0, 30.0, 0.0]), atol=1e-9)
    check_props_do_not_occlude(far, props)
    # the check itself: a point between camera 0 and the centre hides the workspace, one behind does not
    c = default_rig()[0].center
    assert occludes(np.array([[c[0] / 2, c[1] / 2, 1.0]]), default_rig())
    assert not occludes(np.array([[-c[0] / 2, -c[1] / 2, 1.0]]), default_rig())


@pytest.mark.blender
def test_layout_and_file_sizes(built, configs):
    config, _ = configs
    W, H = RIG.image_size
    files = sorted(str(p.relative_to(built)) for p in built.rglob("*") if p.is_file())
    expect = sorted(
        ["rig.json", "README.md", ".silpose-frames.json", ".silpose-output.json", "test-00000-of-00002.parquet",
         "test-00001-of-00002.parquet"]
        + [f"background/{c}/{j:05d}.png" for c in RIG.names for j in range(BACKGROUND)]
        + [f"frames/{c}/{i:05d}.png" for c in RIG.names for i in range(SAMPLES)]
    )
    assert files == expect
    assert not list(built.parent.glob(".*partial*"))
    written = Rig.from_json((built / "rig.json").read_text())
    assert {**written.to_dict(), "source": ""} == {**RIG.to_dict(), "source": ""}  # the same rig; source: its file
    assert written.source.endswith("rig.json")
    for p in built.rglob("*.png"):
        assert _read_rgb(p).shape == (H, W, 3)
        assert 5_000 < p.stat().st_size < 200_000  # noisy 160x120 RGB: neither empty nor raw
    card = (built / "README.md").read_text()
    assert "frames/<camera>/00000.png" in card and "Cycles" in card


@pytest.mark.blender
def test_truth_equals_render_samples(built, clean):
    split = load_split(built, "test", with_masks=True)
    np.testing.assert_array_equal(split.sample_id, np.arange(SAMPLES))
    for i, rec in enumerate(clean["truth"]):
        for name in ("joints", "masks", "contours"):
            np.testing.assert_array_equal(getattr(split, name)[i], rec[name])
        np.testing.assert_array_equal(clean["records"][i]["masks"], rec["masks"])
    assert np.all(split.gait["clip"] > 0)  # library clips (test samples pose held-out clips alone)


@pytest.mark.blender
def test_written_frames_are_the_clean_renders_plus_seeded_noise(built, configs, clean):
    """Determinism across processes: the generator's Cycles renders equal this worker's bit for
    bit, so every PNG equals clean render + the frame's seeded noise."""
    config, _ = configs
    for k, cam in enumerate(RIG.names):
        for i in range(SAMPLES):
            exp = add_camera_noise(clean["frames"][i, k], noise_rng(config.seed, "frames", k, i), SIGMA, FLICKER)
            np.testing.assert_array_equal(_read_rgb(built / "frames" / cam / f"{i:05d}.png"), exp)
        exp = add_camera_noise(clean["empty"][k], noise_rng(config.seed, "background", k, 0), SIGMA, FLICKER)
        np.testing.assert_array_equal(_read_rgb(built / "background" / cam / "00000.png"), exp)


@pytest.mark.blender
def test_background_statistics_match_the_noise_model(built, clean):
    """The written background frames vs the model ``round(g_j * clean + e)`` around the clean
    render of an independent worker: per-frame gains g_j (fitted) within 1 +- flicker and spread,
    per-pixel residual noise of std sigma, per-pixel mean and variance over the frames as the
    model predicts given those gains."""
    pixel_var = SIGMA**2 + 1 / 12  # Gaussian noise + rounding
    for k, cam in enumerate(RIG.names):
        frames = np.stack([_read_rgb(built / "background" / cam / f"{j:05d}.png") for j in range(BACKGROUND)])
        frames, c = frames.astype(np.float64), clean["empty"][k].astype(np.float64)
        ok = (c > 15) & (c < 240)  # away from clipping
        g = (frames * c).sum((1, 2, 3)) / (c * c).sum()
        assert np.all(np.abs(g - 1) < FLICKER + 0.002) and g.std() > FLICKER / 4, g
        resid = (frames - g[:, None, None, None] * c)[:, ok]
        assert abs(resid.mean()) < 0.05 and abs(resid.std() / np.sqrt(pixel_var) - 1) < 0.03, resid.std()
        z = (frames.mean(0) - g.mean() * c)[ok] / np.sqrt(pixel_var / BACKGROUND)
        assert abs(z.mean()) < 0.1 and 0.9 < z.std() < 1.1, (z.mean(), z.std())
        var_model = pixel_var + c[ok] ** 2 * g.var(ddof=1)
        ratio = frames.var(0, ddof=1)[ok].mean() / var_model.mean()
        assert 0.95 < ratio < 1.05, ratio


def _shadow_like(person, empty, mask):
    """Pixels outside ``mask`` darker in every channel by a common factor (a cast shadow)."""
    r = (person + 1.0) / (empty + 1.0)
    return (~mask) & (r.max(-1) < 0.95) & (r.max(-1) - r.min(-1) < 0.12)


@pytest.mark.blender
def test_person_region_matches_the_truth_mask(clean):
    """Clean renders with and without the person: pixels that change strongly are the truth mask,
    except cast shadows (darker by one factor in all channels) and the anti-aliased rim."""
    ious, recalls, strays = [], [], []
    k3 = np.ones((3, 3), np.uint8)
    for i, rec in enumerate(clean["truth"]):
        for k in range(len(RIG)):
            P, E = clean["frames"][i, k].astype(np.float64), clean["empty"][k].astype(np.float64)
            mask = rec["masks"][k].astype(bool)
            differs = np.abs(P - E).max(-1) > 12
            rim = cv2.dilate(mask.astype(np.uint8), k3).astype(bool) & ~cv2.erode(mask.astype(np.uint8), k3).astype(bool)
            shadow = _shadow_like(P, E, mask)
            recalls.append((differs & mask & ~rim).sum() / (mask & ~rim).sum())
            strays.append((differs & ~mask & ~rim & ~shadow).sum() / mask.sum())
            ious.append((differs & mask).sum() / ((differs & ~shadow) | mask).sum())
    print(f"person region vs mask: IoU min {min(ious):.3f}, recall min {min(recalls):.3f}, "
          f"non-shadow changes outside max {max(strays):.3f} of the mask area")
    assert min(recalls) > 0.97
    assert max(strays) < 0.03
    assert min(ious) > 0.9


@pytest.mark.blender
def test_floor_shadow_below_the_person(clean):
    """Outside the mask, the person frame is darker than the empty room by more than the noise
    (3 sigma of the camera noise + the flicker), in a patch at least 5 % of the person's area,
    and mostly in the rows of the lower legs and below."""
    for i, rec in enumerate(clean["truth"]):
        for k in range(len(RIG)):
            P, E = clean["frames"][i, k].mean(-1), clean["empty"][k].mean(-1)
            mask = rec["masks"][k].astype(bool)
            grown = cv2.dilate(mask.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
            dark = (~grown) & (E - P > 3 * SIGMA + FLICKER * E)
            rows = np.flatnonzero(mask.any(1))
            knee_row = rows[0] + 0.7 * (rows[-1] - rows[0])
            ys = np.nonzero(dark)[0]
            print(f"sample {i} view {k}: shadow {dark.sum()} px (person {mask.sum()} px), "
                  f"{(ys >= knee_row).mean():.2f} below the knees")
            assert dark.sum() > 0.05 * mask.sum()
            assert (ys >= knee_row).mean() > 0.8


@pytest.mark.blender
def test_rerun_resumes_and_refuses(built, configs, tmp_path):
    """A complete folder is reported done; a partial one is resumed with identical bytes; another
    configuration is refused."""
    from silpose.datagen.frames.config import frames_from_dict
    from silpose.datagen.frames.generate import FramesError, generate_frames

    config, fcfg = configs
    assert generate_frames(config, fcfg, built, progress=False)["already_complete"]
    other = frames_from_dict(dict(fcfg.to_dict(), background=BACKGROUND + 1))
    with pytest.raises(FramesError, match="another frames dataset"):
        generate_frames(config, other, built, progress=False)

    out = tmp_path / "ds"
    partial = tmp_path / ".ds.partial"
    shutil.copytree(built, partial)
    gone = [partial / "frames" / RIG.names[1] / "00001.png", partial / "background" / RIG.names[0] / "00003.png"]
    before = {p: p.read_bytes() for p in gone}
    for p in gone + [partial / "test-00001-of-00002.parquet"]:
        p.unlink()
    with pytest.raises(FramesError, match="unfinished run of another configuration"):
        generate_frames(config, other, out, progress=False)
    s = generate_frames(config, fcfg, out, workers=2, progress=False)
    assert (s["tasks_rendered"], s["tasks_skipped"]) == (2, 1)  # the background and sample 1
    assert not partial.exists()
    for p, data in before.items():
        assert (out / p.relative_to(partial)).read_bytes() == data
    assert (out / "test-00001-of-00002.parquet").read_bytes() == (built / "test-00001-of-00002.parquet").read_bytes()


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "silpose.datagen.frames.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=120)


def _error_line(r):
    lines = [l for l in r.stderr.splitlines() if l.startswith("silpose gen-frames: error: ")]
    assert r.returncode != 0 and len(lines) == 1, r.stderr
    return lines[0]


@pytest.mark.parametrize(
    "edit, field",
    [("samples = 2", "samples = 0"), ("background = 12", "background = 1"), ("flicker = 0.02", "flicker = -0.1"),
     ("shard_size = 1", "colour = 3"), ("cycles_samples = 16", "cycles_samples = 1.5")],
)
def test_bad_frames_values(tmp_path, edit, field):
    (tmp_path / "rig.json").write_text(RIG.to_json())
    cfg = tmp_path / "bad.toml"
    cfg.write_text(TOML.replace(*(edit, field)))
    r = _cli(cfg, "--out", tmp_path / "ds", "--no-progress")
    line = _error_line(r)
    key = field.split(" = ")[0]
    assert str(cfg) in line and f"frames.{key}" in line, line
    assert not (tmp_path / "ds").exists() and not (tmp_path / ".ds.partial").exists()


def test_bad_cli_input(tmp_path):
    line = _error_line(_cli("nope", "--out", tmp_path / "ds"))
    assert line == "silpose gen-frames: error: nope: unknown preset; available presets: default, motions, paper, smoke"
    line = _error_line(_cli("smoke", "--background", "1", "--out", tmp_path / "ds"))
    assert line.startswith("silpose gen-frames: error: --background (overrides ") and "frames.background" in line
    assert line.endswith("must be an integer in [2, 100000], got 1")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("x")
    line = _error_line(_cli("smoke", "--out", tmp_path / "busy"))
    assert str(tmp_path / "busy") in line and "silpose did not write notes.txt" in line
    assert (tmp_path / "busy" / "notes.txt").read_text() == "x"
    r = _cli("--help")
    assert r.returncode == 0 and "--background" in r.stdout and "--samples" in r.stdout
