"""Real rigs in: ``silpose rig import`` and ``silpose rig show``.

::

    calibration   one camera as a calibration file states it; spelling-insensitive field lookup
    opencv        cv2.FileStorage XML/YAML, one file per camera or one for all
    easymocap     intri.yml + extri.yml
    pose2sim      Pose2Sim / anipose Calib.toml
    skeletool     Skeletool / Captury .calibration (MPI-INF-3DHP, DynaCap)
    colmap        COLMAP sparse models: cameras.txt + images.txt, or cameras.bin + images.bin
    json_layouts  JSON calibrations of other tools (anipose/AIST++, CMU Panoptic, Human3.6M-style, XRPrimer)
    formats       the registry of formats (name, detect, read), reading several files into one camera list
    image_size    from the file, --image-size, or an image/video next to it
    frame         calibration frame -> silpose frame: unit, up axis, floor, origin
    workspace     the largest floor rectangle where a tall person is fully visible (maximal rectangle)
    importer      the whole import, with the notes it prints
    show          a rig in words and in a picture
    examples      example calibrations (the one-wall lab) for tests and docs
    cli           the typer group ``rig`` (entry point in app/pyproject.toml)

The rig data model and rig.json I/O stay in :mod:`silpose.shared.camera` / :mod:`silpose.shared.rig_frame`
(the generator reads them); conventions in docs/conventions.md, "World frame" and "Cameras".
"""
