"""silpose.app: the user workflows. The only package that composes ``silpose.segment`` and ``silpose.model``.

The data path, top to bottom::

    inputs/            read: silhouette PNG folders, dataset splits; check a frames folder's layout; file suffixes
    view_status        the one vocabulary of view statuses (used, empty mask, too small, merged, ...)
    contours           silhouette masks -> view contours, with each view's status
    inference          contours -> the model (silpose.model) -> joints; ``silpose infer`` on silhouettes
    writers            joints (Parquet / JSON), reconstructed contours (.npz), view status per frame (JSON)
    recordings/        every camera input (``silpose infer --videos``, ``--frames``): per-camera videos or frame
                       folders -> masks -> blobs -> joints; several people (floor grid, tracking, per-person views,
                       placement, floor plan) or one (``--people 1``: each view's largest blob); overlays
    training           ``silpose train``: load a dataset, select hyperparameters, fit, report, save
    segment_quality    measurement tool: segmentation IoU on a frames dataset with truth masks
    cli/               the ``train`` and ``infer`` commands (entry points ``silpose.commands``)
    errors             one-line input errors naming the file

    rig/               ``silpose rig import`` / ``silpose rig show``: calibration files (OpenCV, EasyMocap,
                       Pose2Sim/anipose, silpose) -> a rig in silpose's frame with its transform and workspace
"""
