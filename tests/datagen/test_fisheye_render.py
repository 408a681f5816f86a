"""The raster renderer through a fisheye lens (``Camera.fisheye``): the silhouettes of the same bodies rendered
by pinhole cameras and carried pixel by pixel through OpenCV's fisheye model (``cv2.fisheye.undistortPoints`` of
every fisheye pixel, looked up in the pinhole render) are the fisheye renders (Blender has no OpenCV fisheye
camera to compare with)."""

from __future__ import annotations

import multiprocessing as mp

import cv2
import numpy as np

from silpose.datagen.testing import render_scenes_with
from silpose.shared.camera import Camera, Rig, ring_rig

#: four cameras 45 degrees apart, 1280 x 960 (4 x the paper's rig), so a pixel's worth of outline is small
PINHOLE = ring_rig(4, 0.0, 45.0, 7.0, 2.2, (0.0, 0.0, 0.9), 1880.0, 1280, 960)
#: strong enough to change silhouettes near the image centre (theta_d grows 4-10 % faster than theta there)
LENSES = np.array([[2.0, 1.0, -0.5, 0.1], [1.5, 0.5, 0.0, 0.0], [2.5, 0.0, 0.0, 0.0], [1.8, 0.2, 0.1, 0.0]])
FISHEYE = Rig(tuple(Camera(c.name, c.K, c.R, c.t, c.width, c.height, LENSES[i], fisheye=True)
                    for i, c in enumerate(PINHOLE)))


def _config(rig: Rig) -> dict:
    return {"seed": 3, "renderer": "raster", "blender_engine": "workbench", "rig": rig.to_dict(), "n_points": 64,
            "max_redraws": 20}


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def test_fisheye_silhouettes_are_the_pinhole_ones_through_the_lens():
    with mp.get_context("spawn").Pool(1) as pool:
        fish = pool.apply_async(render_scenes_with, (_config(FISHEYE), ["raster"], "test", [0, 1])).get(300)["raster"]
        pin = pool.apply_async(render_scenes_with, (_config(PINHOLE), ["raster"], "test", [0, 1])).get(300)["raster"]
    through, direct = [], []
    for f, p in zip(fish, pin):
        np.testing.assert_array_equal(f["joints"], p["joints"])  # the same bodies
        for k, (cam, pinhole) in enumerate(zip(FISHEYE, PINHOLE)):
            u, v = np.meshgrid(np.arange(cam.width, dtype=np.float64), np.arange(cam.height, dtype=np.float64))
            n = cam.normalised(np.stack([u.ravel(), v.ravel()], axis=1))  # the ray each fisheye pixel sees
            at = n @ pinhole.K[:2, :2].T + pinhole.K[:2, 2]  # where the pinhole camera sees that ray
            maps = at.reshape(cam.height, cam.width, 2).astype(np.float32)
            expected = cv2.remap(p["masks"][k], maps[..., 0], maps[..., 1], cv2.INTER_NEAREST, borderValue=0) > 0
            got = f["masks"][k] > 0
            assert got.sum() > 5000
            through.append(_iou(got, expected))
            direct.append(_iou(got, p["masks"][k] > 0))
    print(f"fisheye renders vs pinhole renders through the lens: IoU min {min(through):.4f}; "
          f"without the lens {max(direct):.4f} at most")
    assert min(through) > 0.98  # measured: 0.987
    assert max(direct) < min(through) - 0.01 and np.mean(direct) < 0.93  # the lens acts (measured: at most 0.970)
