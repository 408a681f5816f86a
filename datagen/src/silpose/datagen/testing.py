"""Test helpers that must live in the installed package (spawned workers import them by name).

Mostly a synthetic stand-in renderer for unit tests of the pipeline (NOT a person, NOT Blender):
``synthetic_render_samples`` has the signature and record layout of
``silpose.datagen.worker.render_samples`` but draws a stick figure with thick OpenCV lines
instead of rendering a body, so IO, sharding, resume and executor logic can be tested in
milliseconds. Every sample is a pure function of ``(config["seed"], split, index)``.
:func:`render_scenes_with` renders the same scenes with several registered renderers (Blender,
in a spawned worker) to compare them through the renderer protocol.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import cv2
import numpy as np

from silpose.shared.camera import Rig
from silpose.shared.contours import extract_contours, normalise
from silpose.shared.seeds import SPLIT_CODE, derive_rng
from silpose.shared.skeleton import BONES, N_JOINTS

from .config import GenConfig, load_config
from .render import rendering
from .renderers import renderer_from_config
from .scene import draw_scene, joints_visible

#: ``render=`` value of ``pipeline.generate`` that uses :func:`synthetic_render_samples`
SYNTH_RENDER = "silpose.datagen.testing:synthetic_render_samples"


def tiny_config_toml(seed: int = 7, shard_size: int = 4, train: int = 8, test: int = 4) -> str:
    """The TOML text of a tiny raster-renderer config (default rig) for pipeline tests."""
    return (f'name = "tiny"\nseed = {seed}\nrenderer = "raster"\nblender_engine = "workbench"\n'
            f"shard_size = {shard_size}\nn_points = 200\nmax_redraws = 50\n[splits]\ntrain = {train}\ntest = {test}\n")


def tiny_config(folder, text: str | None = None) -> GenConfig:
    """A validated GenConfig written to ``folder/tiny.toml`` (``text`` default: :func:`tiny_config_toml`)."""
    path = Path(folder) / "tiny.toml"
    path.write_text(tiny_config_toml() if text is None else text)
    return load_config(path)


SUBJECT_FIELDS = ("height", "shoulder_width", "hip_width")
GAIT_FIELDS = ("phase", "stride", "arm_swing", "knee_flex", "heading", "x", "y")
#: Split key of an unknown split (the stand-in renders any split name).
OTHER_SPLIT_CODE = 9

# A rough standing pose (metres), pelvis at 0.95 m, facing +x.
_REST = np.array(
    [
        [0, 0, 0.95], [0, 0, 1.2], [0, 0, 1.45], [0, 0, 1.58], [0, 0, 1.72],
        [0, 0.18, 1.42], [0, 0.22, 1.15], [0, 0.24, 0.9],
        [0, -0.18, 1.42], [0, -0.22, 1.15], [0, -0.24, 0.9],
        [0, 0.1, 0.92], [0, 0.11, 0.5], [0, 0.11, 0.08], [0.15, 0.11, 0.02],
        [0, -0.1, 0.92], [0, -0.11, 0.5], [0, -0.11, 0.08], [0.15, -0.11, 0.02],
    ],
    dtype=np.float64,
)


def synthetic_record(config: dict, split: str, index: int) -> dict:
    """One synthetic record (see ``silpose.datagen.worker.render_samples`` for the fields).

    Draws from ``derive_rng(seed, SPLIT_CODE[split], index)`` (:data:`OTHER_SPLIT_CODE` for other
    split names): three keys, so never the stream of a real sample draw (four keys).
    """
    rng = derive_rng(config["seed"], SPLIT_CODE.get(split, OTHER_SPLIT_CODE), index)
    rig = Rig.from_dict(config["rig"])
    width, height = rig.image_size
    heading = rng.uniform(-np.pi, np.pi)
    x, y = rng.uniform(-1.0, 1.0, size=2)
    scale = rng.uniform(0.9, 1.1)
    c, s = np.cos(heading), np.sin(heading)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    joints = (_REST * scale + rng.normal(0, 0.02, size=(N_JOINTS, 3))) @ rot.T + [x, y, 0]
    uv = rig.project(joints)  # (K, 19, 2)
    masks = np.zeros((len(rig), height, width), np.uint8)
    for k in range(len(rig)):
        pts = np.round(uv[k] * 16).astype(np.int32)
        for a, b in BONES:
            cv2.line(masks[k], tuple(pts[a]), tuple(pts[b]), 1, thickness=9, lineType=cv2.LINE_8, shift=4)
        cv2.circle(masks[k], tuple(pts[3]), 9 * 16, 1, thickness=-1, shift=4)
    n = int(config["n_points"])
    cont = extract_contours(masks, n)
    _, centroid, scale_px = normalise(cont["points"])
    return {
        "sample_id": int(index),
        "split": split,
        "seed": int(config["seed"]),
        "redraws": int(rng.integers(0, 2)),
        "subject": {"height": float(1.72 * scale), "shoulder_width": 0.36 * scale, "hip_width": 0.2 * scale},
        "gait": {
            "phase": float(rng.uniform()), "stride": 0.7, "arm_swing": 0.3, "knee_flex": 0.5,
            "heading": float(heading), "x": float(x), "y": float(y),
        },
        "joints": joints.astype(np.float32),
        "masks": masks,
        "contours": cont["points"],
        "contour_centroid": centroid.astype(np.float32),
        "contour_scale": scale_px.astype(np.float32),
        "touches_border": cont["touches_border"],
        "n_blobs": cont["n_blobs"],
        "contour_length": cont["length"],
        "area": cont["area"],
    }


def synthetic_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in for ``render_samples``: one synthetic record per index."""
    return [synthetic_record(config, split, i) for i in indices]


def failing_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in that renders ``train`` and fails on every other split (tests worker failures)."""
    if split != "train":
        raise RuntimeError(f"synthetic failure on split {split}")
    return synthetic_render_samples(config, split, indices)


def wrong_ids_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in returning the right records under shifted sample ids (tests the driver's check)."""
    records = synthetic_render_samples(config, split, indices)
    for r in records:
        r["sample_id"] += 1
    return records


def crashing_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in whose worker process dies abruptly on every split but ``train`` (tests the watchdog)."""
    if split != "train":
        os._exit(3)
    return synthetic_render_samples(config, split, indices)


#: ``killing_render_samples`` reads ``"<split>:<index>:<marker file>"`` from this variable.
KILL_ENV = "SILPOSE_TEST_KILL_AT"
#: ``slow_render_samples`` sleeps this many seconds per sample (a float).
DELAY_ENV = "SILPOSE_TEST_RENDER_DELAY"
#: ``slow_render_samples`` creates ``<this folder>/<worker pid>`` when it starts a shard (if set).
STARTED_ENV = "SILPOSE_TEST_RENDER_STARTED"


def killing_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in whose worker SIGKILLs itself once, mid-shard, on a chosen sample (fault drills).

    ``$SILPOSE_TEST_KILL_AT = "<split>:<index>:<marker>"``: on reaching sample ``index`` of ``split``,
    after rendering the shard's earlier samples, the worker creates ``marker`` and kills itself with
    SIGKILL -- unless ``marker`` already exists (so a rerun goes through). Otherwise it is
    ``synthetic_render_samples``.
    """
    spec = os.environ.get(KILL_ENV, "")
    records = []
    for i in indices:
        if spec:
            kill_split, kill_index, marker = spec.split(":", 2)
            if split == kill_split and int(kill_index) == int(i):
                try:
                    os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
                except FileExistsError:
                    pass
                else:
                    os.kill(os.getpid(), signal.SIGKILL)
        records.append(synthetic_record(config, split, i))
    return records


def slow_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """``synthetic_render_samples`` sleeping ``$SILPOSE_TEST_RENDER_DELAY`` s per sample (overlapping runs);
    announces each shard it starts in the folder ``$SILPOSE_TEST_RENDER_STARTED`` when that is set."""
    delay = float(os.environ.get(DELAY_ENV, "0.1"))
    if os.environ.get(STARTED_ENV):
        Path(os.environ[STARTED_ENV], str(os.getpid())).touch()
    records = []
    for i in indices:
        time.sleep(delay)
        records.append(synthetic_record(config, split, i))
    return records


def render_scenes_with(config: dict, names: list[str], split: str, indices: list[int]) -> dict[str, list[dict]]:
    """Render the same scenes with each renderer of ``names``, through the Renderer protocol only.

    Call in a spawned worker (Blender). Scene i is the first draw of sample ``indices[i]`` whose
    joints and (for the first renderer) posed mesh are inside every image.

    Returns:
        ``{name: [{"redraw", "joints" (19, 3), "masks" (K, H, W)} per index]}``.
    """
    rig = Rig.from_dict(config["rig"])
    renderers = [renderer_from_config(config, n) for n in names]
    scenes = []
    with rendering(renderers[0], rig) as first:
        out = {names[0]: []}
        for index in indices:
            for redraw in range(int(config["max_redraws"]) + 1):
                scene = draw_scene(int(config["seed"]), split, index, redraw, rig)
                if not joints_visible(scene):
                    continue
                result = first.render(scene)
                if result.masks is not None:
                    break
            else:
                raise RuntimeError(f"{split} sample {index}: no visible draw")
            scenes.append(scene)
            out[names[0]].append({"redraw": redraw, "joints": result.joints, "masks": result.masks})
    for name, renderer in zip(names[1:], renderers[1:]):
        with rendering(renderer, rig):
            out[name] = []
            for scene in scenes:
                r = renderer.render(scene)
                out[name].append({"redraw": scene.redraw, "joints": r.joints, "masks": r.masks})
    return out
