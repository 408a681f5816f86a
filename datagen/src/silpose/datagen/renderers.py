"""The renderers and the registry that maps config names to them.

Every renderer implements :class:`render.Renderer` and builds the sample's body once through
the Blender adapter (:func:`blender.scene.posed_body`):

- ``raster``: Blender's posed mesh projected with the rig and filled at pixel centres by
  :mod:`.raster` (no Blender render; ~7x faster than Workbench, and a check of the calibration).
- ``blender``: Blender's own silhouette render, Workbench (flat, needs EGL) or Cycles (1 sample,
  box filter), ``blender_engine`` in the config.
- ``textured``: Cycles RGB frames of the clothed person in a furnished room
  (:class:`frames.render.TexturedRenderer`, ``silpose gen-frames``).

A dataset's ``renderer`` must be one of :data:`MASK_RENDERERS`; the two agree to IoU >= 0.99.
"""

from __future__ import annotations

import tempfile
from typing import Any

import numpy as np

from silpose.shared.camera import Rig

from .blender import scene as bs
from .frames.render import TexturedRenderer
from .raster import project_vertices, rasterize_projected
from .render import RenderResult, Renderer, check_scene_rig
from .scene import SampleScene, mesh_visible

#: Vertices closer than this to a camera plane (metres) count as behind it.
MIN_DEPTH_M = 0.05


class MaskRenderer:
    """Shared body of the silhouette renderers: posed body, visibility check, then :meth:`masks`."""

    name = ""

    def __init__(self) -> None:
        self.rig: Rig | None = None

    def open(self, rig: Rig) -> None:
        bs.reset_factory()
        self.rig = rig

    def close(self) -> None:
        self.rig = None

    def render(self, scene: SampleScene) -> RenderResult:
        """Masks of ``scene``, or ``masks=None`` if a posed mesh vertex leaves some image."""
        check_scene_rig(scene, self.rig, self.name)
        with bs.posed_body(scene.subject, scene.pose) as body:
            uv = project_vertices(body.vertices, scene.rig, min_depth=MIN_DEPTH_M)
            if not mesh_visible(uv, scene.rig):
                return RenderResult(joints=body.joints, masks=None)
            return RenderResult(joints=body.joints, masks=self.masks(body, uv))

    def masks(self, body: bs.PosedMesh, uv: np.ndarray) -> np.ndarray:
        """(K, H, W) uint8 silhouettes of ``body`` (still in the Blender scene), ``uv`` (K, V, 2) its projection."""
        raise NotImplementedError


class RasterRenderer(MaskRenderer):
    """``raster``: fill the projected triangles at pixel centres (:func:`raster.rasterize_projected`)."""

    name = "raster"

    @classmethod
    def from_config(cls, config: dict[str, Any]) -> "RasterRenderer":
        return cls()

    def masks(self, body: bs.PosedMesh, uv: np.ndarray) -> np.ndarray:
        width, height = self.rig.image_size
        return rasterize_projected(uv, body.triangles, height, width)


class BlenderRenderer(MaskRenderer):
    """``blender``: Blender's own render of the body, alpha > 0.5 (:func:`blender.scene.render_masks`).

    Args:
        engine: ``"workbench"`` or ``"cycles"`` (:data:`blender.scene.ENGINES`).
    """

    name = "blender"

    def __init__(self, engine: str = "workbench") -> None:
        super().__init__()
        if engine not in bs.ENGINES:
            raise ValueError(f"config field blender_engine: must be one of {bs.ENGINES}, got {engine!r}")
        self.engine = engine
        self._cameras: list = []
        self._tmp: tempfile.TemporaryDirectory | None = None

    @classmethod
    def from_config(cls, config: dict[str, Any]) -> "BlenderRenderer":
        return cls(engine=config.get("blender_engine", "workbench"))

    def open(self, rig: Rig) -> None:
        super().open(rig)
        self._cameras = bs.setup_scene(rig, self.engine)
        self._tmp = tempfile.TemporaryDirectory(prefix="silpose-render-")

    def close(self) -> None:
        if self._tmp is not None:
            self._tmp.cleanup()
        self._tmp, self._cameras = None, []
        super().close()

    def masks(self, body: bs.PosedMesh, uv: np.ndarray) -> np.ndarray:
        return bs.render_masks(self._cameras, self._tmp.name)


#: Config name -> renderer class (each has ``from_config(config_dict)``).
RENDERERS: dict[str, type] = {
    RasterRenderer.name: RasterRenderer,
    BlenderRenderer.name: BlenderRenderer,
    TexturedRenderer.name: TexturedRenderer,
}
#: Renderers a dataset config may name in its ``renderer`` field (they make every sample's masks).
MASK_RENDERERS: tuple[str, ...] = (RasterRenderer.name, BlenderRenderer.name)


class UnknownRendererError(ValueError):
    """A renderer name the registry does not know."""


def get_renderer(name: str) -> type:
    """The renderer class registered as ``name``; UnknownRendererError names the known ones."""
    try:
        return RENDERERS[name]
    except (KeyError, TypeError):
        raise UnknownRendererError(
            f"config field renderer: unknown renderer {name!r}; known: {', '.join(RENDERERS)}"
        ) from None


def renderer_from_config(config: dict[str, Any], name: str | None = None) -> Renderer:
    """A renderer (not yet opened) for a worker config; ``name`` defaults to ``config["renderer"]``."""
    return get_renderer(config["renderer"] if name is None else name).from_config(config)
