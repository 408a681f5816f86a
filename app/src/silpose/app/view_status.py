"""The one vocabulary of view statuses: why each (frame or person-frame, camera) view was used or not.

Every camera input writes these words -- ``silpose infer --videos`` in ``joints.parquet``'s ``view_status``
column and ``summary.json``'s ``camera_status``, ``silpose infer --frames`` in ``<out>.segmentation.json`` --
and docs/conventions.md ("View statuses") lists them with their meaning. A view that is not ``ok`` is a
missing view: the model marginalises it.
"""

from __future__ import annotations

#: the view was used
VIEW_OK = "ok"
#: the person's blob is shared with another tracked person
VIEW_MERGED = "merged"
#: the person's blob also holds something no tracked person explains (a prop, a shadow, someone beyond the room)
VIEW_CLUTTER = "clutter"
#: the person's blob touches the image border (cut outline)
VIEW_BORDER = "border"
#: the person's blob does not span them from the feet to above the hips (a piece of them)
VIEW_PARTIAL = "partial"
#: no usable blob under the person's torso in this camera
VIEW_NOT_SEEN = "not seen"
#: the mask has no foreground at all
VIEW_EMPTY = "empty mask"
#: the largest blob is smaller than the minimum blob area (one person, ``--people 1`` / ``--frames``)
VIEW_TOO_SMALL = "too small"
#: no video, frames folder or readable file for this camera: a missing view in every frame
VIEW_NO_VIDEO = "no video"
#: the camera's video ended (or stopped decoding) before the others: a missing view from there on
VIEW_ENDED = "video ended"
#: the model was not trained on this camera
VIEW_NOT_MODELLED = "not modelled"
#: every view status, in report order
VIEW_STATUSES = (VIEW_OK, VIEW_MERGED, VIEW_CLUTTER, VIEW_BORDER, VIEW_PARTIAL, VIEW_NOT_SEEN, VIEW_EMPTY,
                 VIEW_TOO_SMALL, VIEW_NO_VIDEO, VIEW_ENDED, VIEW_NOT_MODELLED)
