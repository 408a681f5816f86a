"""The Blender adapters: the only modules that import bpy, lazily, inside functions called in spawned
worker processes (docs/conventions.md, "Layers").

- :mod:`.camera`: silpose's OpenCV cameras <-> Blender camera parameters (pure math, no bpy);
- :mod:`.scene`: the body mesh, armature and mask renders;
- :mod:`.bvh`: a BVH clip imported by Blender's own importer (``io_anim_bvh``);
- :mod:`.scene_clip`: an FBX or glTF clip imported by Blender's bundled importers;
- :mod:`.bvh_writer`: an armature fitted to joints, exported by Blender's BVH exporter (``silpose export``).

The textured rooms of camera frames are in :mod:`silpose.datagen.frames.blender_room`.
"""
