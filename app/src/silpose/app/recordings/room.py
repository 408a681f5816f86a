"""The room a rig lives in: its calibration frame (world transform) and its workspace.

Rigs imported from a lab's calibration carry ``rig.transform`` (a
:class:`~silpose.shared.rig_frame.WorldTransform` from the calibration's frame to silpose's) and
``rig.workspace`` (a :class:`~silpose.shared.rig_frame.Workspace`). :func:`rig_room` is the one place
the recordings workflow reads them; rigs that do not carry them (the built-in rig, older model files)
are in silpose's frame with the default 3 m x 3 m workspace.
"""

from __future__ import annotations

from silpose.shared.rig_frame import DEFAULT_WORKSPACE, Workspace, WorldTransform


def rig_room(rig) -> tuple[WorldTransform, Workspace]:
    """(world transform, workspace) of ``rig``; identity and the default workspace when it has none."""
    return getattr(rig, "transform", None) or WorldTransform(), getattr(rig, "workspace", None) or DEFAULT_WORKSPACE
