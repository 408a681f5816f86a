"""The ``textured`` renderer: Cycles RGB frames of a clothed person in a furnished room.

It implements :class:`silpose.datagen.render.Renderer`. ``open(rig)`` starts a fresh Cycles
scene with the rig's cameras and the room of :mod:`.scene` (:func:`blender_room.build_room`);
``render(scene)`` builds the sample's body once (:func:`silpose.datagen.blender.scene.posed_mesh`), copies it
into a static mesh with one material per garment of ``scene.appearance`` and renders every
camera; :meth:`TexturedRenderer.render_empty` renders the room alone with the same scene,
cameras and sampling seed, so room pixels the person does not affect (by occlusion, shadow or
bounce light) have identical clean values in both. The result's ``masks`` are the same posed mesh
filled by the raster renderer (the silhouette truth of the frame).
"""

from __future__ import annotations

import tempfile
import time
from typing import Any

import numpy as np

from silpose.shared.camera import Rig

from . import blender_room as br
from ..blender import scene as bs
from ..raster import project_vertices, rasterize_projected
from ..render import RenderResult, check_scene_rig
from ..scene import SampleScene
from ..subjects import joint_radius_array
from .scene import part_labels

#: Vertices closer than this to a camera plane (metres) count as behind it (as in the mask renderers).
MIN_DEPTH_M = 0.05


class TexturedRenderer:
    """Cycles CPU path tracing of the clothed person (module docstring).

    Args:
        samples: Cycles samples per pixel (fixed seed, no adaptive sampling).
        denoise: OpenImageDenoise on the render.
    """

    name = "textured"

    def __init__(self, samples: int = 16, denoise: bool = True) -> None:
        self.samples, self.denoise = int(samples), bool(denoise)
        self.rig: Rig | None = None
        self._cameras: list = []
        self._tmp: tempfile.TemporaryDirectory | None = None

    @classmethod
    def from_config(cls, config: dict[str, Any]) -> "TexturedRenderer":
        """From a worker config holding ``frames`` = {``cycles_samples``, ``denoise``}."""
        f = config.get("frames")
        if not isinstance(f, dict) or "cycles_samples" not in f or "denoise" not in f:
            raise KeyError("config: missing field 'frames' with 'cycles_samples' and 'denoise'")
        return cls(samples=int(f["cycles_samples"]), denoise=bool(f["denoise"]))

    def open(self, rig: Rig) -> None:
        self._cameras = br.setup_cycles(rig, self.samples, self.denoise)
        br.build_room(rig)
        self.rig = rig
        self._tmp = tempfile.TemporaryDirectory(prefix="silpose-frames-")

    def close(self) -> None:
        if self._tmp is not None:
            self._tmp.cleanup()
        self.rig, self._cameras, self._tmp = None, [], None

    def render_empty(self) -> tuple[np.ndarray, float]:
        """The empty room in every camera: ((K, H, W, 3) float32 RGB display levels 0..255, seconds)."""
        if self.rig is None:
            raise ValueError(f"renderer {self.name!r}: render_empty() before open()")
        t0 = time.perf_counter()
        images = br.render_rgb(self._cameras, self._tmp.name)
        return images, time.perf_counter() - t0

    def render(self, scene: SampleScene) -> RenderResult:
        """The clothed person of ``scene`` (``scene.appearance`` required) in the room."""
        check_scene_rig(scene, self.rig, self.name)
        if scene.appearance is None:
            raise ValueError(f"renderer {self.name!r}: the scene has no appearance (clothing colours)")
        body = bs.posed_mesh(scene.subject, scene.pose)
        width, height = scene.rig.image_size
        uv = project_vertices(body.vertices, scene.rig, min_depth=MIN_DEPTH_M)
        masks = None if uv is None else rasterize_projected(uv, body.triangles, height, width)
        labels = part_labels(body.vertices, body.triangles, body.joints, joint_radius_array(scene.subject),
                             scene.appearance)
        person = br.add_person(body.vertices, body.triangles, labels, scene.appearance)
        try:
            t0 = time.perf_counter()
            images = br.render_rgb(self._cameras, self._tmp.name)
            seconds = time.perf_counter() - t0
        finally:
            bs.delete_objects([person])
        return RenderResult(joints=body.joints, masks=masks, images=images, seconds=seconds)
