"""silpose.app: the user workflows. The only package that composes ``silpose.segment`` and ``silpose.model``.

The data path, top to bottom::

    inputs/            read: silhouette PNG folders, dataset splits, image folders / videos, frames folders
    segmentation       camera frames -> silhouette masks (silpose.segment's background subtraction)
    contours           masks -> view contours, with each view's status (used, empty, too small, ...)
    inference          contours -> the model (silpose.model) -> joints; ``silpose infer`` on silhouettes
    frames_pipeline    ``silpose infer --frames``: frames -> masks -> contours -> joints, chunk by chunk
    writers            joints (Parquet / JSON), reconstructed contours (.npz), segmentation status (JSON)
    overlays           per-frame figures of frames, silhouettes, reconstructions and the inferred pose
    recordings/        ``silpose infer --videos``: per-camera videos of several people -> each person's joints in
                       the room (floor grid, tracking, per-person views, placement, overlay videos, floor plan)
    training           ``silpose train``: load a dataset, select hyperparameters, fit, report, save
    segment_quality    measurement tool: segmentation IoU on a frames dataset with truth masks
    cli/               the ``train`` and ``infer`` commands (entry points ``silpose.commands``)
    errors             one-line input errors naming the file

    rig/               ``silpose rig import`` / ``silpose rig show``: calibration files (OpenCV, EasyMocap,
                       Pose2Sim/anipose, silpose) -> a rig in silpose's frame with its transform and workspace
"""
