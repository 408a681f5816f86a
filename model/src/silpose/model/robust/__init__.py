"""Robust inference: heavy-tailed per-point noise, and the repairs of observed contours it makes.

Modules, lowest first::

    median          the median along the last axis (np.median bit for bit, faster on short rows)
    kernels         compiled loops (numba, imported on first use): the point searches and a pass's weights
    observed_views  the usable observed views of a batch, flattened for per-view repairs
    excursions      loops a shadow, blob or bite adds to an outline, replaced by their chords
    reindex         slides of the points along their outline, undone
    weights         RobustSettings, the per-point biweights, the adaptive noise (the method, in its docstring)
    loop            the reweighted passes and the repairs: robust_infer (called by ShapeStructureModel.infer)
"""

from __future__ import annotations

from .excursions import ExcursionSettings, trim_excursions
from .loop import robust_infer, robust_passes
from .observed_views import ObservedViews, observed_views
from .reindex import ReindexSettings, reindex_contours
from .weights import NOISE_LEVELS, RobustSettings, frame_noise_variance, point_weights, snap_correspondences

__all__ = [
    "ExcursionSettings",
    "NOISE_LEVELS",
    "ObservedViews",
    "ReindexSettings",
    "RobustSettings",
    "frame_noise_variance",
    "observed_views",
    "point_weights",
    "reindex_contours",
    "robust_infer",
    "robust_passes",
    "snap_correspondences",
    "trim_excursions",
]
