"""Poses from the motion library mixed with the procedural walk (``[motion] source = "library"``).

Driver side, :func:`prepare_library` turns the ``[motion]`` section into the dataset's clip list:
entry 0 is the procedural walk (:mod:`silpose.datagen.walk`), entries 1.. the library clips of the
chosen ``groups`` (both splits; :mod:`.library`). Each row's ``gait.clip`` indexes that list, which
the dataset metadata (``config.motion.clips``: name, id, group, split, licence, subject,
description, frames, weight), ``manifest.json`` and the card hold.

Splits hold out *subjects*: a train sample draws from the clips whose library ``split`` is
``train``, a test sample from the ``test`` clips (other people, disjoint clips), so a test pose is
never a near-copy of a training frame.

Per sample (:class:`MixedMotion`, own stream ``derive_rng(MOTION_STREAM, seed, split code,
index, redraw)``): a first uniform number u; u < ``procedural_walk`` (training samples only: test
samples pose held-out clips alone) gives a walk pose (the walk's
parameters uniform on their ranges, :func:`walk.sample_gait`), otherwise a library frame: the
group g with probability ``weights[g]`` (normalised over the groups present in the split), then
one of that group's frames uniformly (every clip of g carries the per-frame weight
``weights[g] / frames of g in the split``), a mirror coin, heading and floor position
(:class:`bvh_motion.BvhMotion`). The ``gait`` fields are :data:`MIX_FIELDS`: ``clip``, ``frame``
(BVH frame of the clip; 0 for the walk), ``mirror`` and the walk's :data:`walk.GAIT_FIELDS` (0 for a
library frame, except ``heading``, ``x``, ``y``).

Part mixing (``part_mix`` > 0, training split only): after those draws, a library frame draws one
more uniform number; below ``part_mix`` a second frame (clip, frame, mirror coin; its heading and
position are drawn and unused) gives the hips and legs (:func:`retarget.combine_legs`) if the mix can
stand on its feet (:func:`retarget.above_feet`; up to :data:`LEGS_TRIES` frames are drawn), recorded in
:data:`PART_FIELDS` (``legs_clip`` -1 for a frame whose legs are its own). With ``part_mix`` 0 the
fields and draws are those above, so the test split and older datasets are unchanged.

Limb swing (``limb_swing`` > 0, training split only): after part mixing, a library frame draws one more
uniform number; below ``limb_swing`` each limb of :data:`retarget.LIMBS` draws a rotation vector (axis
uniform on the sphere, angle uniform in [0, ``limb_swing_deg``]) and the limbs are turned
(:func:`retarget.swing_limbs`) if the pose still stands on its feet (:func:`retarget.above_feet`; up to
:data:`LEGS_TRIES` draws, then no swing), recorded in :data:`SWING_FIELDS` (radians, world axes; zeros: no
swing). With ``limb_swing`` 0 nothing more is drawn or recorded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from silpose.shared.rig_frame import DEFAULT_WORKSPACE, Workspace
from silpose.shared.seeds import MOTION_STREAM

from ..walk import GAIT_FIELDS, sample_gait
from .bvh_motion import BvhMotion
from .config import MotionConfig
from .library import Library, LibraryClip, LibraryError, load_library
from .retarget import LIMBS, above_feet, combine_legs, swing_limbs
from .source import Pose, WalkMotion

#: The per-sample motion parameters of a library dataset (the ``gait`` column's fields).
MIX_FIELDS: tuple[str, ...] = ("clip", "frame", "mirror") + GAIT_FIELDS
#: The second frame's fields of a part-mixed dataset (``[motion] part_mix`` > 0).
PART_FIELDS: tuple[str, ...] = ("legs_clip", "legs_frame", "legs_mirror")
#: The limb-swing rotation vectors of a swung dataset (``[motion] limb_swing`` > 0): radians, world axes.
SWING_FIELDS: tuple[str, ...] = tuple(f"swing_{limb}_{a}" for limb in LIMBS for a in "xyz")
#: Second frames drawn for a part-mixed sample until one stands (:func:`retarget.above_feet`); then its own legs.
LEGS_TRIES = 5
WALK_ENTRY = {"name": "procedural-walk", "id": "procedural-walk", "group": "walk", "split": "train+test",
              "licence": "silpose (MIT), procedural", "subject": "-", "description": "silpose's procedural walk cycle",
              "frames": 0, "weight": 0.0}


def split_weights(clips: list[dict], weights: dict[str, float], split: str) -> dict[int, float]:
    """Per-frame weight of every clip (index into ``clips``) of ``split``: ``weights[g] / frames of g``."""
    frames: dict[str, int] = {}
    for c in clips:
        if c["split"] == split:
            frames[c["group"]] = frames.get(c["group"], 0) + int(c["frames"])
    return {i: float(weights.get(c["group"], 1.0)) / frames[c["group"]]
            for i, c in enumerate(clips) if c["split"] == split and frames[c["group"]] > 0}


@dataclass(frozen=True, eq=False)
class PreparedLibrary:
    """The clips of a ``[motion] source = "library"`` config, checked against the library."""

    library: Library
    rows: tuple[int, ...]
    config: MotionConfig

    def clip_list(self) -> list[dict]:
        """The dataset's clip list: the walk, then the chosen library clips (module docstring)."""
        out = [dict(WALK_ENTRY)]
        lib = self.library.clips
        chosen = [lib[r] for r in self.rows]
        per_split = {s: split_weights(chosen, self.config.weights, s) for s in ("train", "test")}
        for i, c in enumerate(chosen):
            w = per_split.get(c["split"], {}).get(i, 0.0)
            out.append({"name": c["id"], "id": c["id"], "group": c["group"], "split": c["split"],
                        "licence": c["licence"], "subject": str(c.get("subject", "")),
                        "description": c.get("description", ""), "frames": int(c["frames"]), "weight": w,
                        "source": c.get("source", ""), "sha256": c.get("sha256", "")})
        return out

    def metadata(self) -> dict:
        """The ``motion`` entry of the dataset config (metadata, manifest, card)."""
        m = self.config
        fields = MIX_FIELDS + (PART_FIELDS if m.part_mix > 0 else ()) + (SWING_FIELDS if m.limb_swing > 0 else ())
        swing = {"limb_swing": m.limb_swing, "limb_swing_deg": m.limb_swing_deg} if m.limb_swing > 0 else {}
        return {"source": "library", "fields": list(fields), "mirror": m.mirror, "part_mix": m.part_mix, **swing,
                "procedural_walk": m.walk_share, "groups": list(m.groups), "weights": dict(m.weights),
                "library": {"path": m.library, "frames_sha256": self.library.sha256(),
                            "acknowledgement": self.library.manifest.get("acknowledgement", ""),
                            "fps": self.library.manifest.get("fps")},
                "clips": self.clip_list()}

    def worker(self) -> dict:
        """The ``motion`` entry of the render workers' config."""
        return {"source": "library", "library": str(self.library.folder), "mirror": self.config.mirror,
                "procedural_walk": self.config.walk_share, "part_mix": self.config.part_mix,
                "limb_swing": self.config.limb_swing, "limb_swing_deg": self.config.limb_swing_deg,
                "clips": [{"row": int(r), **{k: c[k] for k in ("split", "weight")}}
                          for r, c in zip(self.rows, self.clip_list()[1:])]}


def prepare_library(motion: MotionConfig) -> PreparedLibrary:
    """Load the library and choose the clips of ``motion.groups`` (every group: all of them).

    Raises:
        LibraryError: the library is unreadable, a group is not in it, or a split has no clip
        while the walk share is below 1.
    """
    lib = load_library(motion.library)
    groups = set(c["group"] for c in lib.clips)
    unknown = [g for g in (*motion.groups, *motion.weights) if g not in groups]
    if unknown:
        raise LibraryError(f"{motion.base}: [motion] group {unknown[0]!r} is not in the library "
                           f"(groups: {', '.join(sorted(groups))})")
    want = set(motion.groups) or groups
    rows = tuple(i for i, c in enumerate(lib.clips) if c["group"] in want and int(c["frames"]) > 0)
    if motion.walk_share < 1.0:
        for s in ("train", "test"):
            if not any(lib.clips[r]["split"] == s for r in rows):
                raise LibraryError(f"{motion.base}: [motion] the library has no {s} clip in groups {sorted(want)}")
    return PreparedLibrary(library=lib, rows=rows, config=motion)


class MixedMotion:
    """Library clips of one split mixed with the procedural walk (module docstring)."""

    stream = MOTION_STREAM

    def __init__(self, clips: list[LibraryClip], indices: list[int], walk_share: float, mirror: bool = False,
                 workspace: Workspace = DEFAULT_WORKSPACE, part_mix: float = 0.0, legs_fields: bool = False,
                 limb_swing: float = 0.0, limb_swing_deg: float = 90.0, swing_fields: bool = False):
        """``part_mix``: share of library frames whose legs come from a second frame;
        ``legs_fields``: record :data:`PART_FIELDS` (a part-mixed dataset's test split too);
        ``limb_swing``, ``limb_swing_deg``: share of library frames whose limbs are swung, largest angle (degrees);
        ``swing_fields``: record :data:`SWING_FIELDS` (a swung dataset's test split too)."""
        self.part_mix = float(part_mix) if clips else 0.0
        self.limb_swing = float(limb_swing) if clips else 0.0
        self.max_swing = np.deg2rad(float(limb_swing_deg))
        self.fields = (MIX_FIELDS + (PART_FIELDS if legs_fields or self.part_mix > 0 else ())
                       + (SWING_FIELDS if swing_fields or self.limb_swing > 0 else ()))
        self.walk = WalkMotion(workspace)
        self.walk_share = float(walk_share) if clips else 1.0
        self.indices = list(indices)
        self.local = {g: k for k, g in enumerate(self.indices)}
        self.bvh = BvhMotion(clips, mirror=mirror, workspace=workspace) if clips else None
        self.workspace = workspace

    @classmethod
    def from_config(cls, motion: dict, split: str, workspace: Workspace = DEFAULT_WORKSPACE) -> "MixedMotion":
        """From the render workers' ``motion`` config (:meth:`PreparedLibrary.worker`), for ``split``."""
        lib = load_library(motion["library"])
        clips, indices = [], []
        for i, c in enumerate(motion["clips"], start=1):
            if c["split"] == split and float(c["weight"]) > 0:
                clips.append(LibraryClip(lib, int(c["row"]), float(c["weight"])))
                indices.append(i)
        train = split == "train"
        share = float(motion.get("procedural_walk", 0.0)) if train else 0.0
        part_mix = float(motion.get("part_mix", 0.0))
        swing = float(motion.get("limb_swing", 0.0))
        return cls(clips, indices, share, bool(motion.get("mirror", False)), workspace,
                   part_mix=part_mix if train else 0.0, legs_fields=part_mix > 0,
                   limb_swing=swing if train else 0.0, limb_swing_deg=float(motion.get("limb_swing_deg", 90.0)),
                   swing_fields=swing > 0)

    def draw(self, rng: np.random.Generator) -> dict[str, float]:
        """A walk pose or a library frame, heading and floor position (module docstring)."""
        own_legs = {"legs_clip": -1.0, "legs_frame": 0.0, "legs_mirror": 0.0} if PART_FIELDS[0] in self.fields else {}
        own_legs.update({k: 0.0 for k in SWING_FIELDS} if SWING_FIELDS[0] in self.fields else {})
        if self.bvh is None or rng.random() < self.walk_share:
            return {"clip": 0.0, "frame": 0.0, "mirror": 0.0, **sample_gait(rng, self.workspace), **own_legs}
        p = self.bvh.draw(rng)
        out = {"clip": float(self.indices[int(p["clip"])]), "frame": p["frame"], "mirror": p["mirror"],
               **{k: 0.0 for k in GAIT_FIELDS}, **own_legs}
        out.update(heading=p["heading"], x=p["x"], y=p["y"])
        if self.part_mix > 0 and rng.random() < self.part_mix:
            upper = self.bvh.clips[int(p["clip"])].points(int(p["frame"]), bool(p["mirror"]))
            for _ in range(LEGS_TRIES):
                q = self.bvh.draw(rng)
                lower = self.bvh.clips[int(q["clip"])].points(int(q["frame"]), bool(q["mirror"]))
                if above_feet(combine_legs(upper, lower)):
                    out.update(legs_clip=float(self.indices[int(q["clip"])]), legs_frame=q["frame"],
                               legs_mirror=q["mirror"])
                    break
        if self.limb_swing > 0 and rng.random() < self.limb_swing:
            base = self.points(out)
            for _ in range(LEGS_TRIES):
                axes = rng.normal(size=(len(LIMBS), 3))
                angles = rng.uniform(0.0, self.max_swing, size=len(LIMBS))
                vecs = axes / np.linalg.norm(axes, axis=1, keepdims=True) * angles[:, None]
                swings = dict(zip(LIMBS, vecs))
                if above_feet(swing_limbs(base, swings)):
                    out.update({f"swing_{limb}_{a}": float(v[i]) for limb, v in swings.items()
                                for i, a in enumerate("xyz")})
                    break
        return out

    def points(self, params: dict[str, float]) -> dict[str, np.ndarray]:
        """Role positions (:func:`retarget.clip_points`) of a library sample's frame, its legs from the second
        frame when part-mixed, its limbs swung when swung; ``params`` as :meth:`draw` returns them."""
        c = self.local[int(params["clip"])]
        pts = self.bvh.clips[c].points(int(params["frame"]), bool(params["mirror"]))
        legs = int(params.get("legs_clip", -1))
        if legs >= 0:
            lower = self.bvh.clips[self.local[legs]].points(int(params["legs_frame"]), bool(params["legs_mirror"]))
            pts = combine_legs(pts, lower)
        if any(params.get(k, 0.0) for k in SWING_FIELDS):
            pts = swing_limbs(pts, {limb: np.array([params[f"swing_{limb}_{a}"] for a in "xyz"]) for limb in LIMBS})
        return pts

    def pose(self, subject: dict[str, float], params: dict[str, float]) -> Pose:
        """The walk's or the retargeted clip frame's (or the two part-mixed frames') pose of ``subject``."""
        c = int(params["clip"])
        if c == 0:
            return self.walk.pose(subject, {k: params[k] for k in GAIT_FIELDS})
        return self.bvh.placed(subject, self.points(params), params)
