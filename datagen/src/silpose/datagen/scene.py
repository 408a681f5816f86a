"""The pure description of one sample to render, and how it is drawn from the seeds (no bpy).

A :class:`SampleScene` says everything a renderer needs: who (the subject's body), how posed
(a :class:`motion.Pose` from a motion source), seen by which cameras (the rig) and, for textured
renders, wearing what. Renderers (:mod:`.render`) turn it into masks or images.

Sample ``index`` of ``split``, draw ``redraw``, is a pure function of ``(seed, split, index,
redraw)``: its generator is ``derive_rng(seed, SPLIT_CODE[split], index, redraw)``
(docs/conventions.md, "Seeds"); the subject is drawn first, then the motion parameters (from the
same generator for the walk; from ``derive_rng(motion.stream, seed, SPLIT_CODE[split], index,
redraw)`` for a source with its own stream, e.g. motion-capture clips). A draw
whose person is not fully inside every image is rejected by the caller and redrawn with
``redraw + 1`` (:func:`joints_visible` before any rendering, :func:`mesh_visible` on the posed
mesh).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from silpose.shared.camera import Rig
from silpose.shared.seeds import SPLIT_CODE, derive_rng

from .motion.source import WALK, MotionSource, Pose, WalkMotion
from .subjects import joint_radius_array, sample_subject

#: Pixels kept free between the person and the image border.
BORDER_MARGIN_PX = 1.0


@dataclass(frozen=True, eq=False)
class SampleScene:
    """One sample to render.

    Attributes:
        split, index, redraw: which draw of which sample (``redraw`` = rejected draws before it).
        subject: body shape parameters (``subjects.SUBJECT_FIELDS``).
        motion: the motion source's parameters (``walk.GAIT_FIELDS`` for the walk), stored with
            the sample.
        pose: the posed skeleton the renderer builds the body in.
        rig: the calibrated cameras.
        appearance: clothing colours for textured renders (``frames.scene.draw_appearance``), or
            None for silhouettes.
    """

    split: str
    index: int
    redraw: int
    subject: dict[str, float]
    motion: dict[str, float]
    pose: Pose
    rig: Rig
    appearance: dict | None = None


def sample_rng(seed: int, split: str, index: int, redraw: int) -> np.random.Generator:
    """The generator of draw ``redraw`` of sample ``index`` of ``split`` (module docstring)."""
    if split not in SPLIT_CODE:
        raise ValueError(f"split must be one of {tuple(SPLIT_CODE)}, got {split!r}")
    return derive_rng(seed, SPLIT_CODE[split], index, redraw)


def draw_sample_parameters(
    seed: int, split: str, index: int, redraw: int, motion: MotionSource = WALK
) -> tuple[dict, dict]:
    """(subject, motion parameters) of one draw: subject first from :func:`sample_rng`, then motion
    (from the same generator, or from the source's own stream; module docstring)."""
    rng = sample_rng(seed, split, index, redraw)
    subject = sample_subject(rng, split)
    stream = getattr(motion, "stream", None)
    motion_rng = rng if stream is None else derive_rng(stream, seed, SPLIT_CODE[split], index, redraw)
    params = motion.draw(motion_rng)
    return subject, params


def draw_scene(
    seed: int, split: str, index: int, redraw: int, rig: Rig, motion: MotionSource | None = None,
    appearance: dict | None = None,
) -> SampleScene:
    """The scene of draw ``redraw`` of sample ``index`` of ``split`` (a pure function of its arguments).

    ``motion`` defaults to the walk on the rig's workspace (``WalkMotion(rig.workspace)``).
    """
    if motion is None:
        motion = WalkMotion(rig.workspace)
    subject, params = draw_sample_parameters(seed, split, index, redraw, motion)
    return SampleScene(split=split, index=int(index), redraw=int(redraw), subject=subject, motion=params,
                       pose=motion.pose(subject, params), rig=rig, appearance=appearance)


def joints_visible(scene: SampleScene, margin_px: float = BORDER_MARGIN_PX) -> bool:
    """Cheap pre-check: every posed joint, grown by its skin radius, projects inside every image.

    Uses the pose's forward-kinematics joints only (no Blender). A joint of radius ``r`` at depth
    ``z`` must lie ``r * fx / z + margin_px`` pixels inside the border.
    """
    J = scene.pose.joints
    r = joint_radius_array(scene.subject)
    for cam in scene.rig:
        z = cam.to_camera(J)[:, 2]
        if np.any(z <= 0.1):
            return False
        px = cam.project(J)
        if not np.all(np.isfinite(px)):  # beyond the lens model's domain: not seen
            return False
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
