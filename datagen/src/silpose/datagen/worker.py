"""Render one shard of samples inside a spawned worker process (the driver never imports bpy).

Every sample is a pure function of ``(config["seed"], split, index)``: its draws come from
``np.random.default_rng(np.random.SeedSequence([seed, SPLIT_CODE[split], index, redraw]))``.
A draw whose person is not fully inside every image is rejected and redrawn with
``redraw + 1``: first from the forward-kinematics joints (cheap, before Blender builds
anything), then from Blender's posed mesh projected with the rig (before rendering), and
last from the rendered masks (empty, or touching the image border). ``redraws`` counts the
rejected draws.
"""

from __future__ import annotations

import tempfile
from typing import Any

import numpy as np

from silpose.shared.camera import Rig
from silpose.shared.contours import extract_contours, normalise
from silpose.shared.skeleton import JOINT_NAMES, N_JOINTS

from .subjects import SUBJECT_FIELDS, joint_radii, sample_subject
from .walk import GAIT_FIELDS, posed_body, root_transform, sample_gait, skeleton_positions

SPLIT_CODE = {"train": 0, "test": 1}
RENDERERS = ("raster", "blender")
#: Pixels kept free between the person and the image border.
BORDER_MARGIN_PX = 1.0


class SampleError(RuntimeError):
    """A sample could not be produced (e.g. no visible draw within ``max_redraws``)."""


def sample_rng(seed: int, split: str, index: int, redraw: int) -> np.random.Generator:
    """The generator of draw ``redraw`` of sample ``index`` of ``split``."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), SPLIT_CODE[split], int(index), int(redraw)]))


def draw_sample_parameters(seed: int, split: str, index: int, redraw: int) -> tuple[dict, dict]:
    """(subject, gait) of one draw: subject first, then gait, from :func:`sample_rng`."""
    rng = sample_rng(seed, split, index, redraw)
    subject = sample_subject(rng, split)
    gait = sample_gait(rng)
    return subject, gait


def joints_visible(
    subject: dict, gait: dict, rig: Rig, margin_px: float = BORDER_MARGIN_PX, joints: np.ndarray | None = None
) -> bool:
    """Cheap pre-check: every joint, grown by its skin radius, projects inside every image.

    Uses forward kinematics only (no Blender). A joint of radius ``r`` at depth ``z`` must lie
    ``r * fx / z + margin_px`` pixels inside the border. ``joints`` (19, 3) world metres are
    :func:`walk.skeleton_positions` if already computed.
    """
    J = skeleton_positions(subject, gait) if joints is None else joints
    radii = joint_radii(subject)
    r = np.array([radii[n[2:] if n[:2] in ("l_", "r_") else n] for n in JOINT_NAMES])
    for cam in rig:
        z = cam.to_camera(J)[:, 2]
        if np.any(z <= 0.1):
            return False
        px = cam.project(J)
        m = r * cam.K[0, 0] / z + margin_px
        x, y = px[:, 0], px[:, 1]
        if np.any(x < -0.5 + m) or np.any(x > cam.width - 0.5 - m) or np.any(y < -0.5 + m) or np.any(y > cam.height - 0.5 - m):
            return False
    return True


def mesh_visible(uv: np.ndarray | None, rig: Rig, margin_px: float = BORDER_MARGIN_PX) -> bool:
    """Every projected mesh vertex ``uv`` (K, V, 2) lies ``margin_px`` inside its image.

    ``uv`` is :func:`raster.project_vertices`'s result (None: a vertex is behind a camera).
    """
    if uv is None:
        return False
    return all(np.all(cam.in_image(uv[k], margin=margin_px)) for k, cam in enumerate(rig))


def _check_config(config: dict) -> tuple[int, str, str, Rig, int, int]:
    for key in ("seed", "renderer", "rig", "n_points", "max_redraws"):
        if key not in config:
            raise KeyError(f"config: missing field {key!r}")
    renderer = config["renderer"]
    if renderer not in RENDERERS:
        raise ValueError(f"config field renderer: must be one of {RENDERERS}, got {renderer!r}")
    engine = config.get("blender_engine", "workbench")
    rig = Rig.from_dict(config["rig"], source="config field rig")
    n_points, max_redraws = int(config["n_points"]), int(config["max_redraws"])
    if n_points < 3:
        raise ValueError(f"config field n_points: must be >= 3, got {n_points}")
    if max_redraws < 0:
        raise ValueError(f"config field max_redraws: must be >= 0, got {max_redraws}")
    return int(config["seed"]), renderer, engine, rig, n_points, max_redraws


def make_record(
    index: int, split: str, seed: int, redraws: int, subject: dict, gait: dict, joints: np.ndarray, masks: np.ndarray, n_points: int
) -> dict[str, Any]:
    """Assemble one output record (see :func:`render_samples`) from masks and parameters."""
    c = extract_contours(masks, n_points)
    _, centroid, scale = normalise(c["points"])
    return {
        "sample_id": int(index),
        "split": split,
        "seed": int(seed),
        "redraws": int(redraws),
        "subject": {k: float(subject[k]) for k in SUBJECT_FIELDS},
        "gait": {k: float(gait[k]) for k in GAIT_FIELDS},
        "joints": np.asarray(joints, np.float32).reshape(N_JOINTS, 3),
        "masks": masks.astype(np.uint8),
        "contours": c["points"].astype(np.float32),
        "contour_centroid": centroid.astype(np.float32),
        "contour_scale": scale.astype(np.float32),
        "touches_border": c["touches_border"].astype(bool),
        "n_blobs": c["n_blobs"].astype(np.int32),
        "contour_length": c["length"].astype(np.float32),
        "area": c["area"].astype(np.int32),
    }


def render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Render samples ``indices`` of ``split`` ("train" or "test") -- one shard.

    Pure function of ``(config["seed"], split, index)`` per sample. Imports bpy (only here).

    Args:
        config: ``seed`` (int), ``renderer`` ("raster" | "blender"), ``blender_engine``
            ("workbench" | "cycles", blender renderer only), ``rig`` (``Rig.to_dict()``),
            ``n_points`` (contour points), ``max_redraws``.
        split: "train" or "test".
        indices: sample indices.
    Returns:
        one dict per index, in order: ``sample_id``, ``split``, ``seed``, ``redraws``,
        ``subject`` (SUBJECT_FIELDS), ``gait`` (GAIT_FIELDS), ``joints`` (19, 3) float32 world
        metres, ``masks`` (K, H, W) uint8 {0,1}, ``contours`` (K, n, 2) float32 px,
        ``contour_centroid`` (K, 2), ``contour_scale`` (K,), ``touches_border`` (K,) bool,
        ``n_blobs`` (K,) int32, ``contour_length`` (K,) float32, ``area`` (K,) int32.
    Raises:
        SampleError: no fully visible draw within ``max_redraws`` redraws.
    """
    if split not in SPLIT_CODE:
        raise ValueError(f"split must be one of {tuple(SPLIT_CODE)}, got {split!r}")
    seed, renderer, engine, rig, n_points, max_redraws = _check_config(config)
    from . import blender_scene as bs
    from .raster import project_vertices, rasterize_projected

    width, height = rig.image_size
    bs.reset_factory()
    cameras = bs.setup_scene(rig, engine) if renderer == "blender" else []
    out = []
    with tempfile.TemporaryDirectory(prefix="silpose-render-") as tmp:
        for index in indices:
            for redraw in range(max_redraws + 1):
                subject, gait = draw_sample_parameters(seed, split, index, redraw)
                posed = posed_body(subject, gait)
                root = root_transform(subject, gait, posed)
                fk_joints = posed[0] @ root[:3, :3].T + root[:3, 3]
                if not joints_visible(subject, gait, rig, joints=fk_joints):
                    continue
                arm, body = bs.build_body(subject)
                try:
                    bs.pose_body(arm, subject, gait, root)
                    vertices, triangles = bs.evaluated_mesh(body)
                    uv = project_vertices(vertices, rig, min_depth=0.05)
                    if not mesh_visible(uv, rig):
                        continue
                    joints = bs.evaluated_joints(arm)
                    if renderer == "raster":
                        masks = rasterize_projected(uv, triangles, height, width)
                    else:
                        masks = bs.render_masks(cameras, tmp)
                finally:
                    bs.delete_objects([body, arm])
                if np.any(masks.reshape(len(rig), -1).max(axis=1) == 0):
                    continue
                rec = make_record(index, split, seed, redraw, subject, gait, joints, masks, n_points)
                if np.any(rec["touches_border"]):
                    continue
                out.append(rec)
                break
            else:
                raise SampleError(
                    f"{split} sample {index} (seed {seed}): no draw fully visible in every view after "
                    f"{max_redraws + 1} draws (config field max_redraws)"
                )
    return out
