"""Textured camera frames (``silpose gen-frames``): a person walking in a furnished room, rendered
by Cycles, plus empty-room frames and the silhouette truth.

Modules: :mod:`.config` (the ``[frames]`` section), :mod:`.scene` (room, props, lights and
clothing as data, no bpy), :mod:`.render` (the ``textured`` renderer), :mod:`.worker` (a task in a
spawned worker), :mod:`.generate` (the folder: plan, resume, write), :mod:`.card`, :mod:`.cli`.
Nothing is imported here, so importing one module does not load the others.
"""
