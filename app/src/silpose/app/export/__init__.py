"""``silpose export``: joints written by ``silpose infer`` into the files motion-capture tools read.

::

    motion     the joints files ``silpose infer`` writes (a dataset's or PNG folder's, a recording's), read into
               one :class:`~.motion.Motion` (frames x 19 joints, a frame rate, units and axes)
    formats    the registry of exporters, ``Exporter(name, suffix, write)``: TRC, C3D, BVH
    trc        TRC as OpenSim and Pose2Sim read it
    c3d_file   C3D through the ``c3d`` library
    cli        the ``silpose export`` command (entry point in app/pyproject.toml)

BVH goes through Blender's own exporter in a spawned worker (:mod:`silpose.datagen.bvh_export`): the app
never imports bpy. Units, axes and frame rate of each format: docs/conventions.md, "Export".
"""
