"""Every camera input: per-camera videos or frame folders -> joints (``silpose infer --videos``, ``--frames``).

Several people are placed in the room (``pipeline``); one person (``--people 1``, ``one_person``) takes each
view's largest blob. One concept per module, in data-path order::

    sources        the videos folder: match videos to the rig's cameras, probe, synchronise, stream frames
    frames_source  the frames-folder layout (frames/ + background/) as a source of the same reader
    silhouettes    frames -> masks: mask videos binarised, or colour videos through the background model
    blobs          a mask's connected components, and a blob's contour
    floor          people on the floor: occupancy grid of every camera's mask
    tracking       floor positions over time -> stable person ids (Hungarian assignment)
    views          per person and camera, the blob that is theirs alone, or why the view is missing
    placement      the root in the room (floor position, stature, silhouettes) and missing views' contours
    writers        joints.parquet + joints.csv, streamed
    overlay_video  per-camera overlay videos
    overlay_messages, overlay_worker  the frames to draw sent down a pipe to the worker process that draws them
    overlay_png    overlays as one tiled PNG per frame; ``--overlays png|mp4|none``
    floorplan      the tracks seen from above
    camera_step    one camera step by step: its frame's mask and blobs, static clutter made background
    step_people    one step's people: floor detection, tracking, visual hulls, each camera's view of each person
    chunk_rows     a chunk of steps' people -> rows (inference, placement, fit), written one per person; overlays
    pipeline       the run of several people: ``run_recording``
    one_person     the run of one person: ``run_one_person``
"""
