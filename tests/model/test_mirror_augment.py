"""Mirrored people as training rows (silpose.model.augment.mirror_samples / training_rows).

The reference is a rendering: a 3D body reflected in the rig's mirror plane and rasterised by the camera
that sees it, against the mirrored rows computed from the unreflected body's silhouettes.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.model.augment import Roughness, augment_rows, mirror_samples, training_rows
from silpose.shared.camera import default_rig, ring_rig
from silpose.shared.contours import extract_contours, signed_area
from silpose.shared.rig_symmetry import rig_mirrors
from silpose.shared.skeleton import BONES, JOINT_INDEX

N_POINTS = 64


def _body(rng: np.random.Generator) -> np.ndarray:
    """(19, 3) world joints of an asymmetric pose: left arm raised sideways, right leg forward, random
    heading and position in the default workspace."""
    j = {
        "pelvis": (0, 0, 0.95), "spine": (0, 0, 1.2), "neck": (0, 0, 1.5), "head": (0, 0, 1.62), "head_top": (0, 0, 1.78),
        "l_shoulder": (0, 0.2, 1.45), "l_elbow": (0, 0.45, 1.55), "l_wrist": (0, 0.68, 1.7),
        "r_shoulder": (0, -0.2, 1.45), "r_elbow": (0.05, -0.25, 1.18), "r_wrist": (0.12, -0.27, 0.95),
        "l_hip": (0, 0.1, 0.92), "l_knee": (-0.05, 0.11, 0.5), "l_ankle": (-0.12, 0.12, 0.08), "l_toe": (0.0, 0.12, 0.02),
        "r_hip": (0, -0.1, 0.92), "r_knee": (0.22, -0.1, 0.55), "r_ankle": (0.3, -0.1, 0.12), "r_toe": (0.42, -0.1, 0.05),
    }
    joints = np.array([j[name] for name in sorted(JOINT_INDEX, key=JOINT_INDEX.get)], dtype=float)
    th = rng.uniform(0, 2 * np.pi)
    R = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1.0]])
    return joints @ R.T + np.r_[rng.uniform(-1.0, 1.0, 2), 0.0]


def _render(rig, joints: np.ndarray) -> np.ndarray:
    """(V, H, W) uint8 masks: discs of 6 cm radius along every bone, rasterised per camera."""
    masks = []
    for cam in rig:
        m = np.zeros((cam.height, cam.width), np.uint8)
        for a, b in BONES:
            for s in np.linspace(0, 1, 25):
                p = (1 - s) * joints[a] + s * joints[b]
                x, y = cam.project(p[None])[0]
                r = 0.06 * cam.K[0, 0] / np.linalg.norm(cam.center - p)
                cv2.circle(m, (int(round(x)), int(round(y))), int(round(r)), 1, -1)
        masks.append(m)
    return np.stack(masks)


def _chirality(joints: np.ndarray) -> np.ndarray:
    """(N,) sign of (left hip - right hip) x (right toe - right ankle) . up: +1 for a person's left side on
    the left of where the feet point, as for every real person; -1 for a mirror image left unrelabelled."""
    lr = joints[:, JOINT_INDEX["l_hip"]] - joints[:, JOINT_INDEX["r_hip"]]
    fwd = joints[:, JOINT_INDEX["r_toe"]] - joints[:, JOINT_INDEX["r_ankle"]]
    return np.sign(np.cross(fwd, lr)[:, 2])


def test_mirrored_rows_equal_the_rendering_of_the_mirrored_person():
    rig = default_rig()
    (mirror,) = rig_mirrors(rig)
    rng = np.random.default_rng(7)
    bodies = np.stack([_body(rng) for _ in range(4)])
    contours = np.stack([extract_contours(_render(rig, b), N_POINTS)["points"] for b in bodies])
    c_m, j_m = mirror_samples(contours, bodies, mirror, rig)
    reflected = mirror.reflect(bodies)
    rendered = np.stack([extract_contours(_render(rig, b), N_POINTS)["points"] for b in reflected])
    gap = np.linalg.norm(c_m - rendered, axis=-1)  # point by point: same start point, same direction
    assert gap.max() < 1e-3, gap.max()  # the discs rasterise mirror-exactly, so only float32 rounding is left
    assert np.all(signed_area(c_m) > 0)  # clockwise, as every contour
    # the joints are the reflected body's, with left and right relabelled
    np.testing.assert_allclose(np.sort(j_m.reshape(-1, 3), axis=0), np.sort(reflected.reshape(-1, 3), axis=0))
    assert np.all(_chirality(bodies) == 1) and np.all(_chirality(j_m) == 1)
    assert np.all(_chirality(reflected) == -1)  # what the relabelling repairs


def test_mirroring_twice_gives_the_samples_back():
    rig = ring_rig(n_cameras=6, azimuth_step_deg=60.0)
    rng = np.random.default_rng(3)
    bodies = np.stack([_body(rng) for _ in range(3)])
    contours = np.stack([extract_contours(_render(rig, b), N_POINTS)["points"] for b in bodies])
    for mirror in rig_mirrors(rig):
        c2, j2 = mirror_samples(*mirror_samples(contours, bodies, mirror, rig), mirror, rig)
        np.testing.assert_allclose(c2, contours, atol=1e-9)
        np.testing.assert_allclose(j2, bodies, atol=1e-12)


def test_training_rows_without_mirrors_are_the_roughness_rows_bit_for_bit():
    rng = np.random.default_rng(0)
    c = rng.uniform(50, 150, (5, 4, N_POINTS, 2)).astype(np.float32)
    j = rng.normal(size=(5, 19, 3)).astype(np.float32)
    ids = np.array([3, 9, 11, 20, 21])
    a = training_rows(c, j, ids, roughness=Roughness(), seed=4)
    b = augment_rows(c, j, Roughness(), 4, ids)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))


def test_training_rows_order_and_streams():
    rig = default_rig()
    mirrors = tuple(rig_mirrors(rig))
    rng = np.random.default_rng(1)
    bodies = np.stack([_body(rng) for _ in range(3)])
    contours = np.stack([extract_contours(_render(rig, b), N_POINTS)["points"] for b in bodies])
    ids = np.array([5, 6, 7])
    c, j = training_rows(contours, bodies, ids, rig=rig, mirrors=mirrors, roughness=Roughness(), seed=2)
    assert c.shape == (12, 4, N_POINTS, 2) and j.shape == (12, 19, 3)
    c_m, j_m = mirror_samples(contours, bodies, mirrors[0], rig)
    np.testing.assert_array_equal(c[:3], contours)
    np.testing.assert_array_equal(c[3:6], c_m)
    np.testing.assert_allclose(j[3:6], j_m)
    # the ragged copies: of the samples, then of the mirrored people (their own streams, whatever the batch)
    alone = training_rows(contours[1:2], bodies[1:2], ids[1:2], rig=rig, mirrors=mirrors, roughness=Roughness(), seed=2)[0]
    np.testing.assert_array_equal(alone[2], c[7]) and np.testing.assert_array_equal(alone[3], c[10])
    assert not np.allclose(c[6:9], c[9:12][:, ::-1])
    with pytest.raises(ValueError, match="rig"):
        training_rows(contours, bodies, ids, mirrors=mirrors)
    with pytest.raises(ValueError, match="shape"):
        mirror_samples(contours[:, :3], bodies, mirrors[0], rig)
