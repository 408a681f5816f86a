"""The renderer interface: a :class:`scene.SampleScene` in, a :class:`RenderResult` out.

Every renderer implements :class:`Renderer`: ``open(rig)`` once per worker process (a fresh
Blender session, cameras, a room), ``render(scene)`` per sample, ``close()`` at the end.
:func:`rendering` pairs open and close. The implementations and the registry that maps config
names to them are in :mod:`.renderers`; none of them imports bpy at module level (only the
Blender adapter modules do, inside spawned workers; docs/conventions.md, "Blender").
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Protocol, TypeVar, runtime_checkable

import numpy as np

from silpose.shared.camera import Rig

from .scene import SampleScene


@dataclass(frozen=True, eq=False)
class RenderResult:
    """What a renderer returns for one scene.

    Attributes:
        joints: (19, 3) float64 posed joints read back from the rendered body, world metres.
        masks: (K, H, W) uint8 silhouettes in {0, 1}, rig order; None when the posed body mesh
            leaves some image (or lies behind a camera): the caller redraws, nothing was rendered.
        images: (K, H, W, 3) float32 RGB display levels 0..255 (textured renderers), else None.
        seconds: wall time of the image renders (s; 0 when nothing was rendered by Blender).
    """

    joints: np.ndarray
    masks: np.ndarray | None
    images: np.ndarray | None = None
    seconds: float = 0.0


@runtime_checkable
class Renderer(Protocol):
    """A renderer of :class:`scene.SampleScene` s (module docstring)."""

    #: The config name the registry (:data:`renderers.RENDERERS`) knows it by.
    name: str

    def open(self, rig: Rig) -> None:
        """Per-process setup for scenes seen by ``rig`` (call once, in the worker)."""
        ...

    def render(self, scene: SampleScene) -> RenderResult:
        """Render one scene (``scene.rig`` must be the rig passed to :meth:`open`)."""
        ...

    def close(self) -> None:
        """Release what :meth:`open` set up."""
        ...


R = TypeVar("R", bound=Renderer)


@contextmanager
def rendering(renderer: R, rig: Rig) -> Iterator[R]:
    """``renderer.open(rig)``, yield it, then ``renderer.close()`` (also on errors)."""
    renderer.open(rig)
    try:
        yield renderer
    finally:
        renderer.close()


def check_scene_rig(scene: SampleScene, rig: Rig | None, name: str) -> None:
    """Raise ValueError unless renderer ``name`` was opened with ``scene.rig``."""
    if rig is None:
        raise ValueError(f"renderer {name!r}: render() before open()")
    if scene.rig is not rig and scene.rig.to_dict() != rig.to_dict():
        raise ValueError(f"renderer {name!r}: the scene's rig differs from the rig the renderer was opened with")
