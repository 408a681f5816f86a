"""The motion-capture motion source: poses drawn from BVH clips, retargeted onto each subject.

A :class:`BvhMotion` implements :class:`motion.MotionSource` from the render workers' ``motion``
config (:meth:`clips.PreparedMotion.worker`). Its parameters (:data:`clips.BVH_FIELDS`, stored in
the dataset's ``gait`` column) are ``clip`` (index into the dataset's clip list, card and
metadata ``config.motion.clips``), ``frame`` (0-based BVH frame of that clip), ``mirror`` (0 or
1), ``heading`` (radians, counter-clockwise from world +x) and ``x``, ``y`` (metres, pelvis on the
floor). They are drawn from their own stream ``derive_rng(MOTION_STREAM, seed, split code, index,
redraw)`` (``silpose.shared.seeds``), in this order: a clip and frame (every used frame weighted
by its clip's ``weight``), a mirror coin (always drawn; used when ``mirror`` is on), heading
uniform on [0, 2 pi), x and y uniform on the workspace. The subject still comes from the sample
draw, so a BVH dataset and a procedural one with the same seed have the same bodies.

The pose: the clip frame retargeted onto the subject (:func:`retarget.retarget_frame`), turned to
the drawn heading, moved to (x, y) and lowered or lifted so that the lowest heel or toe touches
the floor (:func:`walk.foot_points`), as the walk does.
"""

from __future__ import annotations

import numpy as np

from silpose.shared.rig_frame import DEFAULT_WORKSPACE, Workspace
from silpose.shared.seeds import MOTION_STREAM

from .clips import BVH_FIELDS, read_entry
from .joint_maps import UPRIGHT, ResolvedMap
from .source import Pose
from .retarget import clip_points, local_rotations, retarget_frame
from ..walk import euler_matrix, foot_points


class ClipSource:
    """One clip in a render worker: memory-mapped positions, used frames, joint map, weight."""

    def __init__(self, spec: dict):
        arrays = read_entry(spec["cache"], mmap=True)
        self.name = str(spec["name"])
        self.heads, self.tails = arrays.heads, arrays.tails
        self.scale = float(spec["scale"])
        self.weight = float(spec["weight"])
        first, last, stride = (int(v) for v in spec["used"])
        self.used = np.arange(first, last + 1, stride, dtype=np.int64)
        m = spec["map"]
        self.jmap = ResolvedMap(name=str(m["name"]), index={k: int(v) for k, v in m["index"].items()},
                                spine_chain=tuple(int(v) for v in m["spine_chain"]), head_tail=bool(m["head_tail"]),
                                upright=tuple(tuple(float(v) for v in row) for row in m.get("upright", UPRIGHT)),
                                rest_up=str(m.get("rest_up", "+z")))

    def points(self, frame: int, mirror: bool) -> dict[str, np.ndarray]:
        """Role positions of BVH frame ``frame`` in metres (:func:`retarget.clip_points`)."""
        heads = np.asarray(self.heads[frame], np.float64) * self.scale
        tails = np.asarray(self.tails[frame], np.float64) * self.scale
        return clip_points(heads, tails, self.jmap, mirror)


class BvhMotion:
    """Poses from motion-capture clips (module docstring)."""

    fields = BVH_FIELDS
    stream = MOTION_STREAM

    def __init__(self, clips: list[ClipSource], mirror: bool = False, workspace: Workspace = DEFAULT_WORKSPACE):
        if not clips:
            raise ValueError("BvhMotion needs at least one clip")
        self.clips = list(clips)
        self.mirror = bool(mirror)
        self.workspace = workspace
        w = np.array([c.weight * len(c.used) for c in self.clips], np.float64)
        self._cum = np.cumsum(w) / w.sum()

    @classmethod
    def from_config(cls, motion: dict, workspace: Workspace = DEFAULT_WORKSPACE) -> "BvhMotion":
        """From the render workers' ``motion`` config (:meth:`clips.PreparedMotion.worker`), placing
        people on ``workspace`` (the rig's)."""
        return cls([ClipSource(c) for c in motion["clips"]], mirror=bool(motion.get("mirror", False)),
                   workspace=workspace)

    def draw(self, rng: np.random.Generator) -> dict[str, float]:
        """Clip, frame, mirror, heading and floor position (module docstring)."""
        c = int(min(np.searchsorted(self._cum, rng.random(), side="right"), len(self.clips) - 1))
        frame = int(self.clips[c].used[int(rng.integers(len(self.clips[c].used)))])
        coin = rng.random() < 0.5
        heading = float(rng.uniform(0.0, 2 * np.pi))
        (x0, x1), (y0, y1) = self.workspace.bounds
        x = float(rng.uniform(x0, x1))
        y = float(rng.uniform(y0, y1))
        return {"clip": float(c), "frame": float(frame), "mirror": float(coin and self.mirror), "heading": heading,
                "x": x, "y": y}

    def pose(self, subject: dict[str, float], params: dict[str, float]) -> Pose:
        """The retargeted pose of ``subject`` for ``params`` (module docstring)."""
        clip = self.clips[int(params["clip"])]
        return self.placed(subject, clip.points(int(params["frame"]), bool(params["mirror"])), params)

    def placed(self, subject: dict[str, float], pts: dict[str, np.ndarray], params: dict[str, float]) -> Pose:
        """The pose of role positions ``pts`` (:func:`retarget.clip_points`) retargeted onto
        ``subject``, turned to ``params["heading"]``, at ``params["x"], params["y"]``, feet on the floor."""
        J, G, _ = retarget_frame(pts, subject)
        root = np.eye(4)
        root[:3, :3] = euler_matrix((0.0, 0.0, float(params["heading"])))
        root[:3, 3] = (float(params["x"]), float(params["y"]), -float(foot_points(subject, J, G)[:, 2].min()))
        joints = J @ root[:3, :3].T + root[:3, 3]
        return Pose(rotations=local_rotations(G), root=root, joints=joints)
