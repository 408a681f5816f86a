"""The result of :meth:`ShapeStructureModel.infer <silpose.model.shape_model.ShapeStructureModel.infer>`:
per-frame arrays, and the row operations callers need without listing its fields.

Every array field of :class:`InferenceResult` (and of its nested :class:`~silpose.model.hypotheses.Hypotheses`)
is per frame: its first axis has one entry per frame. Optional fields are None when the inference that made
the result does not produce them (robust weights without ``robust``, hypotheses without ``hypotheses``...).
:meth:`InferenceResult.take` selects frames, :meth:`InferenceResult.put` writes frames inferred again,
:meth:`InferenceResult.merge` assembles the results of disjoint sets of frames, and
:meth:`InferenceResult.nan_like` / :meth:`InferenceResult.nan` give frames without any observed view: NaN where
nothing was inferred, or a field's own fill value (``field(metadata={"fill": ...})``: integer fields -1 and
bool fields False unless they say otherwise).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from silpose.shared.skeleton import N_JOINTS

from .hypotheses import Hypotheses

__all__ = ["InferenceResult"]


@dataclass
class InferenceResult:
    """Output of :meth:`ShapeStructureModel.infer` for N frames and K modelled views.

    Attributes:
        joints: (N, 19, 3) root-relative joints, metres, mixture posterior mean.
        joints_best: (N, 19, 3) the most probable component's conditional mean, metres.
        joint_std: (N, 19, 3) posterior standard deviation per coordinate, metres.
        contours_norm: (N, K, n, 2) reconstructed normalised contours of every modelled view.
        contours_px: (N, K, n, 2) reconstructions in pixels; NaN where the view's normalisation is unknown.
        centroid: (N, K, 2) px normalisation centroid used (NaN where unknown).
        scale: (N, K) px normalisation scale used (NaN where unknown).
        views_present: (N, K) bool, which modelled views were observed.
        responsibilities: (N, M) component posteriors given the observed rows.
        log_marginal: (N,) log density of the observed rows under the prior (nats; with robust inference
            still that of the observed input).
        views: rig indices of the K modelled views.
        plausibility: (N,) % of held-out training inputs with the same view subset whose log marginal is
            lower (``silpose.model.plausibility``); None when the model has no calibration for this noise.
        implausible: (N,) bool, plausibility below the calibration's flag percentile; None as above.
        hypotheses: the top-K hypotheses (``infer(hypotheses=K)``), else None.
        robust_weights: (N, K, n) final per-point weights of robust inference (0 for absent views), else None.
        log_marginal_robust: (N,) log density of the last robust pass's pseudo-observations, else None.
        noise_variance: (N,) observation noise s^2 each frame was conditioned with by robust inference's
            adaptive noise (``silpose.model.robust``), else None (the model's or the given s^2).
        excursions_trimmed: (N, K) bool, views whose excursions (shadows, blobs, bitten holes) robust inference
            trimmed before its final pass (``silpose.model.robust.excursions``; ``robust_weights`` then index the
            trimmed contour), else None.
        reindexed: (N, K) bool, views whose points robust inference slid back along their outline before its final
            pass (``silpose.model.robust.reindex``), else None.
        robust_input_px: (N, K, n, 2) the observed contours robust inference's final pass started from: the input
            with those excursions trimmed and slides undone (``robust_weights`` index these points), else None.
    """

    joints: np.ndarray
    joints_best: np.ndarray
    joint_std: np.ndarray
    contours_norm: np.ndarray
    contours_px: np.ndarray
    centroid: np.ndarray
    scale: np.ndarray
    views_present: np.ndarray
    responsibilities: np.ndarray
    log_marginal: np.ndarray
    views: tuple[int, ...] = field(default=())
    plausibility: np.ndarray | None = None
    implausible: np.ndarray | None = None
    hypotheses: Hypotheses | None = None
    robust_weights: np.ndarray | None = field(default=None, metadata={"fill": 0.0})
    log_marginal_robust: np.ndarray | None = None
    noise_variance: np.ndarray | None = None
    excursions_trimmed: np.ndarray | None = None
    reindexed: np.ndarray | None = None
    robust_input_px: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.joints)

    def take(self, rows) -> "InferenceResult":
        """The result of frames ``rows`` (indices, a slice or an (N,) bool mask)."""
        return _map(self, lambda a, f: a[rows])

    def put(self, rows, part: "InferenceResult") -> None:
        """Write ``part``, the result of frames ``rows`` of this one inferred again, into this result's arrays (in
        place). Only the top-level arrays both results have are written; ``views`` must agree."""
        _check_views([self, part])
        for f in dataclasses.fields(self):
            value, new = getattr(self, f.name), getattr(part, f.name)
            if isinstance(value, np.ndarray) and isinstance(new, np.ndarray):
                value[rows] = new

    def nan_like(self, n: int | None = None) -> "InferenceResult":
        """A result of ``n`` frames (None: as many as this one) without any observed view, with the fields this
        one has: NaN, or each field's fill value (module doc)."""
        n = len(self) if n is None else int(n)
        return _map(self, lambda a, f: np.full((n,) + a.shape[1:], _fill(f, a.dtype), dtype=a.dtype))

    @classmethod
    def merge(cls, parts: Sequence["InferenceResult"], order: Sequence, n: int) -> "InferenceResult":
        """One ``n``-frame result from ``parts``, the frames of ``parts[i]`` going to indices ``order[i]``
        (together a partition of 0..n-1). A field some parts lack is filled there as by :meth:`nan_like`."""
        if not parts or len(parts) != len(order):
            raise ValueError(f"merge needs one index array per part, got {len(parts)} parts and {len(order)} orders")
        _check_views(parts)
        return _merge(parts, [np.asarray(o) for o in order], int(n))

    @classmethod
    def nan(cls, n: int, views: Sequence[int], n_points: int, n_components: int, *, plausibility: bool = False,
            hypotheses: int = 0, robust: bool = False) -> "InferenceResult":
        """A result of ``n`` frames without any observed view, with the fields an inference with these options
        gives: the plausibility (a model calibrated for its noise), ``hypotheses`` top hypotheses, the robust
        fields."""
        k = len(views)

        def nan(*shape):
            return np.full((n,) + shape, np.nan)

        res = cls(joints=nan(N_JOINTS, 3), joints_best=nan(N_JOINTS, 3), joint_std=nan(N_JOINTS, 3),
                  contours_norm=nan(k, n_points, 2), contours_px=nan(k, n_points, 2), centroid=nan(k, 2), scale=nan(k),
                  views_present=np.zeros((n, k), bool), responsibilities=nan(n_components), log_marginal=nan(),
                  views=tuple(views))
        if plausibility:
            res.plausibility, res.implausible = nan(), np.zeros(n, dtype=bool)
        if hypotheses > 0:
            kh = int(hypotheses)
            res.hypotheses = Hypotheses(nan(kh, N_JOINTS, 3), nan(kh), np.zeros((n, kh), dtype=np.intp), nan(kh),
                                        np.zeros(n, dtype=np.intp))
        if robust:
            res.robust_weights, res.log_marginal_robust, res.noise_variance = nan(k, n_points), nan(), nan()
            res.excursions_trimmed, res.reindexed = np.zeros((n, k), bool), np.zeros((n, k), bool)
            res.robust_input_px = nan(k, n_points, 2)
        return res.nan_like()  # every field at its fill value


def _fill(f: dataclasses.Field, dtype: np.dtype):
    """The value a frame without any observed view has in field ``f`` of dtype ``dtype``."""
    if "fill" in f.metadata:
        return f.metadata["fill"]
    if dtype == bool:
        return False
    return -1 if np.issubdtype(dtype, np.integer) else np.nan


def _map(obj, fn):
    """A copy of the result (or Hypotheses) ``obj`` with ``fn(array, field)`` applied to every per-frame array."""
    out = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, np.ndarray):
            value = fn(value, f)
        elif dataclasses.is_dataclass(value):
            value = _map(value, fn)
        out[f.name] = value
    return type(obj)(**out)


def _as_slice(idx: np.ndarray):
    """``idx`` (k,) as a slice when it is a run of consecutive ascending indices (a block of a batch: copied as one
    contiguous piece, not gathered), else as it is."""
    if isinstance(idx, slice):
        return idx
    if idx.ndim == 1 and len(idx) and int(idx[-1]) - int(idx[0]) == len(idx) - 1 and np.all(np.diff(idx) == 1):
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


def _merge(parts: list, order: list[np.ndarray], n: int):
    """:meth:`InferenceResult.merge` of results or of Hypotheses. A field every part has is written into an
    uninitialised array (the parts cover every frame: no fill pass over arrays of up to ~100 MB); contiguous
    blocks are copied as slices."""
    order = [_as_slice(o) for o in order]
    out = {}
    for f in dataclasses.fields(parts[0]):
        values = [getattr(p, f.name) for p in parts]
        have = [v for v in values if v is not None]
        if not have or not (isinstance(have[0], np.ndarray) or dataclasses.is_dataclass(have[0])):
            out[f.name] = values[0]
            continue
        if dataclasses.is_dataclass(have[0]):  # nested per-frame arrays (hypotheses)
            filled = [v if v is not None else _map(have[0], lambda a, g: np.full((_count(idx),) + a.shape[1:],
                                                                                 _fill(g, a.dtype), dtype=a.dtype))
                      for v, idx in zip(values, order)]
            out[f.name] = _merge(filled, order, n)
            continue
        shapes = {v.shape[1:] for v in have}
        if len(shapes) > 1:
            raise ValueError(f"merge: the parts' {f.name} have different shapes per frame: {sorted(shapes)}")
        dtype = np.result_type(*have)
        shape = (n,) + have[0].shape[1:]
        arr = np.empty(shape, dtype) if len(have) == len(values) else np.full(shape, _fill(f, dtype), dtype=dtype)
        for v, idx in zip(values, order):
            if v is not None:
                arr[idx] = v
        out[f.name] = arr
    return type(parts[0])(**out)


def _count(idx) -> int:
    return idx.stop - idx.start if isinstance(idx, slice) else len(idx)


def _check_views(parts) -> None:
    views = {tuple(p.views) for p in parts}
    if len(views) > 1:
        raise ValueError(f"results of different modelled views cannot be combined: {sorted(views)}")
