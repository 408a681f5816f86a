"""Where a sample's pose comes from: the procedural walk and motion-capture clips (pure numpy, no bpy).

- :mod:`.source`: the :class:`~.source.Pose` seam, the :class:`~.source.MotionSource` protocol and
  the procedural walk (:data:`~.source.WALK`), re-exported here;
- :mod:`.config`: the ``[motion]`` section of a generation config;
- :mod:`.bvh_check`, :mod:`.joint_maps`, :mod:`.clips`: BVH files, their joints, the import cache
  (the import itself is Blender's, :mod:`silpose.datagen.blender.bvh`, in spawned workers);
- :mod:`.retarget`, :mod:`.bvh_motion`: clip frames retargeted onto every subject.
"""

from .source import BONES, WALK, MotionSource, Pose, WalkMotion

__all__ = ["BONES", "WALK", "MotionSource", "Pose", "WalkMotion"]
