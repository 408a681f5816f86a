"""Recordings: per-camera videos of several people -> each person's joints in the room (``silpose infer --videos``).

One concept per module, in data-path order::

    sources        the videos folder: match videos to the rig's cameras, probe, synchronise, stream frames
    silhouettes    frames -> masks: mask videos binarised, or colour videos through the background model
    blobs          a mask's connected components, and a blob's contour
    floor          people on the floor: occupancy grid of every camera's mask
    tracking       floor positions over time -> stable person ids (Hungarian assignment)
    views          per person and camera, the blob that is theirs alone, or why the view is missing
    placement      the root in the room (floor position, stature, silhouettes) and missing views' contours
    writers        joints.parquet + joints.csv, streamed
    overlay_video  per-camera overlay videos
    floorplan      the tracks seen from above
    pipeline       the run: ``run_recording``
"""
