"""Eval test fixtures: a tiny stick-figure dataset written with the real dataset writer.

``stick_dataset`` is a TEST FIXTURE, not the real generator: thick-limbed stick figures
(walk-like poses, random heading, position and proportions) projected with the default rig,
rasterised with OpenCV, contours extracted with ``silpose.shared.contours``. Contours depend
on the joints, so the model has something to learn; it needs neither Blender nor datagen.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.shared.camera import default_rig
from silpose.shared.contours import extract_contours, normalise
from silpose.shared.dataset import build_metadata, shard_name, write_shard

N_POINTS = 40


def _pose(rng: np.random.Generator, tall: float) -> np.ndarray:
    """(19, 3) world joints of a walk-like pose."""
    ph = rng.uniform(0, 2 * np.pi)
    hip = 0.45 * tall
    a_l, a_r = 0.4 * np.sin(ph), -0.4 * np.sin(ph)
    k_l, k_r = 0.5 * max(0.0, np.sin(ph + 1.0)), 0.5 * max(0.0, -np.sin(ph + 1.0))
    s_l, s_r = -0.5 * a_l, -0.5 * a_r
    def leg(side, a, k):
        h = np.array([0, side * 0.1 * tall, hip])
        kn = h + 0.24 * tall * np.array([np.sin(a), 0, -np.cos(a)])
        an = kn + 0.24 * tall * np.array([np.sin(a - k), 0, -np.cos(a - k)])
        return [h, kn, an, an + np.array([0.08 * tall, 0, -0.02])]
    def arm(side, s):
        sh = np.array([0, side * 0.13 * tall, 0.82 * tall])
        el = sh + 0.17 * tall * np.array([np.sin(s), 0.1 * side, -np.cos(s)])
        wr = el + 0.15 * tall * np.array([np.sin(s + 0.3), 0, -np.cos(s + 0.3)])
        return [sh, el, wr]
    pelvis = np.array([0, 0, hip])
    body = [pelvis, [0, 0, 0.65 * tall], [0, 0, 0.85 * tall], [0, 0, 0.92 * tall], [0, 0, tall]]
    j = np.array(body + arm(1, s_l) + arm(-1, s_r) + leg(1, a_l, k_l) + leg(-1, a_r, k_r), dtype=float)
    th = rng.uniform(0, 2 * np.pi)
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    return j @ R.T + np.r_[rng.uniform(-0.8, 0.8, 2), 0.0]


def _masks(rig, joints: np.ndarray, width_m: float) -> np.ndarray:
    from silpose.shared.skeleton import BONES

    out = []
    for cam in rig.cameras:
        px = cam.project(joints)
        depth = float(np.linalg.norm(cam.center - joints[0]))
        thick = max(2, int(round(width_m * cam.K[0, 0] / depth)))
        m = np.zeros((cam.height, cam.width), np.uint8)
        for a, b in BONES:
            cv2.line(m, tuple(np.round(px[a]).astype(int)), tuple(np.round(px[b]).astype(int)), 1, thick)
        cv2.circle(m, tuple(np.round(px[3]).astype(int)), int(thick * 1.1), 1, -1)
        out.append(m)
    return np.stack(out)


def write_stick_dataset(root, n_train: int, n_test: int, seed: int = 0) -> None:
    rig = default_rig()
    meta = build_metadata(rig.to_dict()["cameras"], {"name": "stick-fixture", "seed": seed}, N_POINTS, "test")
    for split, n, offset, tall_range in (("train", n_train, 0, (1.6, 1.85)), ("test", n_test, 100000, (1.55, 1.9))):
        records = []
        for i in range(n):
            rng = np.random.default_rng(np.random.SeedSequence([seed, offset + i]))
            tall = rng.uniform(*tall_range)
            joints = _pose(rng, tall)
            masks = _masks(rig, joints, 0.11 if split == "train" else 0.13)
            c = extract_contours(masks, N_POINTS)
            _, cen, sc = normalise(c["points"])
            records.append({
                "sample_id": offset + i, "split": split, "seed": seed, "redraws": 0,
                "subject": {"height": float(tall)}, "gait": {"phase": 0.0},
                "joints": joints.astype(np.float32), "masks": masks, "contours": c["points"].astype(np.float32),
                "contour_centroid": cen.astype(np.float32), "contour_scale": sc.astype(np.float32),
                "contour_length": c["length"].astype(np.float32), "area": c["area"].astype(np.int32),
                "n_blobs": c["n_blobs"].astype(np.int32), "touches_border": c["touches_border"],
            })
        write_shard(root / shard_name(split, 0, 1), records, meta)


@pytest.fixture(scope="session")
def stick_dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("stick") / "stick"
    root.mkdir()
    write_stick_dataset(root, n_train=120, n_test=8)
    return root
