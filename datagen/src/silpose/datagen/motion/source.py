"""Motion sources: where a sample's pose comes from (pure numpy, no bpy).

A :class:`Pose` is the seam between motion and rendering: one local rotation per bone plus the
body -> world transform, with the posed joints they give. Renderers only read a ``Pose``; they
never know whether it came from the procedural walk cycle (:class:`WalkMotion`, the default) or
from motion-capture clips (:class:`bvh_motion.BvhMotion`); a source only has to implement
:class:`MotionSource`.

Bones and frames are those of :mod:`.walk`: one bone per non-root joint, named after its child
joint; a bone's rotation is about the body axes of the REST pose; forward kinematics
``G_c = G_parent(c) R_c``, ``p_c = p_parent + G_c (rest_c - rest_parent)``; then the root
transform maps the body frame to the world (docs/conventions.md, "Skeleton" and "World frame").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from silpose.shared.rig_frame import DEFAULT_WORKSPACE, Workspace
from silpose.shared.skeleton import JOINT_NAMES

from ..walk import GAIT_FIELDS, euler_matrix, joint_angles, posed_body, root_transform, sample_gait

#: Bone names (a bone is named after its child joint), in ``JOINT_NAMES`` order.
BONES: tuple[str, ...] = tuple(JOINT_NAMES[1:])


@dataclass(frozen=True, eq=False)
class Pose:
    """A posed skeleton of one subject.

    Attributes:
        rotations: ``{bone: (3, 3) rotation}`` for every bone of :data:`BONES`, about the body
            axes of the rest pose (what the Blender armature's pose bones receive).
        root: (4, 4) body -> world transform (metres).
        joints: (19, 3) posed joint positions, world metres, ``JOINT_NAMES`` order (forward
            kinematics of ``rotations`` on the subject's rest skeleton, then ``root``).
    """

    rotations: Mapping[str, np.ndarray]
    root: np.ndarray
    joints: np.ndarray


@runtime_checkable
class MotionSource(Protocol):
    """Draws motion parameters and turns them into a :class:`Pose` of a subject.

    ``fields`` are the keys of the parameter dict (stored with every sample, the ``gait``
    column). ``stream`` None: ``draw`` consumes the sample's generator after the subject's draws;
    an integer: ``draw`` gets its own generator ``derive_rng(stream, seed, split code, index,
    redraw)`` (:func:`scene.draw_sample_parameters`).
    """

    fields: tuple[str, ...]
    stream: int | None

    def draw(self, rng: np.random.Generator) -> dict[str, float]: ...

    def pose(self, subject: dict[str, float], params: dict[str, float]) -> Pose: ...


class WalkMotion:
    """The procedural walk cycle of :mod:`.walk` (parameters :data:`walk.GAIT_FIELDS`), walkers
    placed anywhere in ``workspace`` (default: the built-in 3 m x 3 m square)."""

    fields = GAIT_FIELDS
    stream = None

    def __init__(self, workspace: Workspace = DEFAULT_WORKSPACE):
        self.workspace = workspace

    def draw(self, rng: np.random.Generator) -> dict[str, float]:
        """Gait parameters, uniform on ``walk.gait_ranges(self.workspace)``."""
        return sample_gait(rng, self.workspace)

    def pose(self, subject: dict[str, float], params: dict[str, float]) -> Pose:
        """The walk pose of ``subject`` at gait ``params``, feet on the floor."""
        angles = joint_angles(params)
        rotations = {bone: euler_matrix(angles[bone]) for bone in BONES}
        posed = posed_body(subject, params)
        root = root_transform(subject, params, posed)
        joints = posed[0] @ root[:3, :3].T + root[:3, 3]
        return Pose(rotations=rotations, root=root, joints=joints)


#: The default motion source (on the built-in workspace; :func:`.scene.draw_scene` walks on the rig's).
WALK = WalkMotion()
