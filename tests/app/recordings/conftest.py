"""Fixtures of the recordings tests (``silpose infer --videos``).

Two kinds of input:

- cheap ones, no Blender: the lab rig (:func:`silpose.datagen.lab.lab_rig`), "people" drawn as the image of
  an upright cylinder (radius 0.2 m, 1.7 m tall) at known floor points (:func:`cylinder_masks`), written as
  mask videos, and a tiny model fitted in memory on stick-figure records of that rig
  (``silpose.datagen.testing.synthetic_record``): for the input checks, statuses and files;
- the generated lab recording (session-scoped, Blender in a spawned worker): two walkers crossing in front
  of the four cameras (:func:`silpose.datagen.lab.make_lab_recording`, lossy mask videos), a small dataset
  rendered for the lab rig with the real generator and a small model trained on it with the real trainer;
  and colour videos composited from the same masks with an empty-room clip (``silpose.segment.composite``).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.datagen.lab import LAB_FPS, lab_rig
from silpose.datagen.testing import synthetic_record
from silpose.model import ShapeStructureModel

#: frames of the generated lab recording (the walkers cross around frame 28)
LAB_FRAMES = 50
#: training samples of the lab-rig dataset
LAB_TRAIN = 240
LAB_POINTS = 100


def cylinder_masks(rig, positions, radius: float = 0.2, height: float = 1.7, base: float = 0.0) -> np.ndarray:
    """(K, H, W) uint8 0/255: each camera's image of upright cylinders at floor points ``positions`` (P, 2),
    standing ``base`` metres above the floor (on a platform)."""
    w, h = rig.image_size
    out = np.zeros((len(rig), h, w), np.uint8)
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    for k, cam in enumerate(rig):
        for x, y in np.asarray(positions, float).reshape(-1, 2):
            ring = np.stack([x + radius * np.cos(ang), y + radius * np.sin(ang)], 1)
            pts = np.concatenate([np.c_[ring, np.full(24, base)], np.c_[ring, np.full(24, base + height)]])
            px = cam.project(pts).astype(np.float32)
            cv2.fillConvexPoly(out[k], np.round(cv2.convexHull(px)).astype(np.int32), 255)
    return out


def write_video(path, frames, fps: float = LAB_FPS) -> None:
    """Write (N, H, W) grey or (N, H, W, 3) BGR uint8 frames as an mp4v video."""
    frames = np.asarray(frames)
    colour = frames.ndim == 4
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (frames.shape[2], frames.shape[1]), isColor=colour)
    assert w.isOpened()
    for f in frames:
        w.write(f)
    w.release()


def walk(start, end, n):
    """(n, 2) floor points from ``start`` to ``end``."""
    return np.linspace(start, end, n)


def write_mask_videos(folder, rig, tracks, fps: float = LAB_FPS, cameras=None) -> None:
    """Mask videos ``<camera>.mp4`` of cylinders moving along ``tracks`` (list of (n, 2) arrays)."""
    folder.mkdir(parents=True, exist_ok=True)
    n = len(tracks[0])
    frames = np.stack([cylinder_masks(rig, np.stack([t[i] for t in tracks])) for i in range(n)], 1)  # (K, n, H, W)
    for k, cam in enumerate(rig):
        if cameras is None or cam.name in cameras:
            write_video(folder / f"{cam.name}.mp4", frames[k], fps)


@pytest.fixture(scope="session")
def rig():
    return lab_rig()


@pytest.fixture(scope="session")
def tiny_model(rig):
    """A 2-component model of the lab rig fitted on 60 stick-figure records (no Blender; joints meaningless)."""
    config = {"seed": 5, "rig": rig.to_dict(), "n_points": 40}
    recs = [synthetic_record(config, "train", i) for i in range(60)]
    c = np.stack([r["contours"] for r in recs])
    j = np.stack([r["joints"] for r in recs])
    return ShapeStructureModel(2, 4, n_init=1, max_iter=30).fit(c, j, rig=rig)


@pytest.fixture(scope="session")
def tiny_model_file(tiny_model, tmp_path_factory):
    from silpose.model.persistence import save_model

    path = tmp_path_factory.mktemp("tiny-model") / "tiny.npz"
    save_model(path, tiny_model)
    return path


@pytest.fixture(scope="session")
def two_cylinders(rig, tmp_path_factory):
    """Mask videos of two cylinders walking past each other, 20 frames (crossing in depth, apart in x)."""
    folder = tmp_path_factory.mktemp("cyl") / "videos"
    write_mask_videos(folder, rig, [walk((-1.0, -0.6), (1.0, -0.6), 20), walk((1.0, 0.7), (-1.0, 0.7), 20)])
    return folder


@pytest.fixture(scope="session")
def lab(tmp_path_factory):
    """The generated lab recording (:func:`silpose.datagen.lab.make_lab_recording`): masks/, truth.npz, ..."""
    from silpose.datagen.lab import make_lab_recording

    return make_lab_recording(tmp_path_factory.mktemp("lab") / "lab", n_frames=LAB_FRAMES)


def train_small_model(root, rig):
    """``root/lab.npz``: a small model (M 3, q 12) trained by the real generator and trainer on :data:`LAB_TRAIN`
    walkers rendered for ``rig``."""
    from silpose.app.training import run_training
    from silpose.datagen.config import load_config
    from silpose.datagen.pipeline import generate

    (root / "lab_rig.json").write_text(rig.to_json())
    (root / "lab.toml").write_text(
        f'name = "lab"\nseed = 0\nrenderer = "raster"\nshard_size = 120\nn_points = {LAB_POINTS}\nmax_redraws = 50\n'
        f'[splits]\ntrain = {LAB_TRAIN}\ntest = 0\n[rig]\nfile = "lab_rig.json"\n')
    generate(load_config(root / "lab.toml"), root / "data", workers=2, progress=False)
    out = root / "lab.npz"
    run_training(str(root / "data"), out=out, progress=False, n_components=3, n_latent=12, n_init=1, max_iter=60)
    return out


@pytest.fixture(scope="session")
def lab_model(tmp_path_factory):
    """A small model trained (real generator and trainer) on a dataset rendered for the lab rig."""
    return train_small_model(tmp_path_factory.mktemp("labdata"), lab_rig())


@pytest.fixture(scope="session")
def lab_colour(lab):
    """Colour videos of the lab recording (people composited over a textured room, floor shadows, noise;
    ``silpose.segment.composite``) and an empty-room clip per camera: ``colour/`` and ``empty/``."""
    from silpose.datagen.lab import unpack_masks
    from silpose.segment.composite import background_frames, composite_frame, room

    masks = unpack_masks(np.load(lab / "truth.npz")).any(axis=1)  # (T, K, H, W)
    (lab / "colour").mkdir(exist_ok=True)
    (lab / "empty").mkdir(exist_ok=True)
    for k, cam in enumerate(lab_rig()):
        size = (cam.width, cam.height)
        clean = room(k, size)
        write_video(lab / "colour" / f"{cam.name}.mp4",
                    np.stack([composite_frame(masks[f, k], k, f, clean=clean) for f in range(len(masks))]))
        write_video(lab / "empty" / f"{cam.name}.mp4", background_frames(k, size, 20))
    return lab


@pytest.fixture(scope="session")
def tools():
    """The helpers above, for the test modules (``--import-mode=importlib`` cannot import conftest)."""
    from types import SimpleNamespace

    return SimpleNamespace(cylinder_masks=cylinder_masks, write_video=write_video, walk=walk,
                           write_mask_videos=write_mask_videos)
