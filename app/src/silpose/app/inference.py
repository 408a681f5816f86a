"""Contours -> the model -> joints, and the ``silpose infer`` workflow for silhouettes.

:func:`infer_rows` runs :meth:`ShapeStructureModel.infer` on the frames that have at least one
usable modelled view and gives the others NaN rows (the camera-frames path can lose every view of
a frame). :func:`run_inference` is ``silpose infer MODEL INPUT``: INPUT is a dataset folder
(:mod:`.inputs.dataset`) or per-camera silhouette PNG folders (:mod:`.inputs.silhouettes`); it
writes the joints and optionally the reconstructed contours (:mod:`.writers`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.model.persistence import load_model
from silpose.model.shape_model import InferenceResult, ShapeStructureModel
from silpose.shared.skeleton import N_JOINTS

from .errors import InferenceInputError
from .inputs.dataset import is_dataset, read_dataset_input
from .inputs.silhouettes import read_png_input
from .writers import sibling, write_contours, write_joints

_ARRAY_FIELDS = ("joints", "joints_best", "joint_std", "contours_norm", "contours_px", "centroid", "scale",
                 "views_present", "responsibilities", "log_marginal")


def nan_result(model: ShapeStructureModel, n: int) -> InferenceResult:
    """An InferenceResult of ``n`` frames without any usable view: NaN everywhere, no view present."""
    lay = model.layout_
    k, p, m = len(lay.views), lay.n_points, len(model.mixture_.weights_)
    nan = lambda *shape: np.full((n,) + shape, np.nan)  # noqa: E731
    return InferenceResult(joints=nan(N_JOINTS, 3), joints_best=nan(N_JOINTS, 3), joint_std=nan(N_JOINTS, 3),
                           contours_norm=nan(k, p, 2), contours_px=nan(k, p, 2), centroid=nan(k, 2), scale=nan(k),
                           views_present=np.zeros((n, k), bool), responsibilities=nan(m), log_marginal=nan(),
                           views=lay.views)


def merge_results(parts: list[InferenceResult], order: list[np.ndarray], n: int) -> InferenceResult:
    """One n-row InferenceResult from ``parts`` whose rows go to indices ``order[i]``."""
    ref = parts[0]
    arrays = {}
    for f in _ARRAY_FIELDS:
        a = getattr(ref, f)
        out = np.empty((n,) + a.shape[1:], a.dtype)
        for p, idx in zip(parts, order):
            out[idx] = getattr(p, f)
        arrays[f] = out
    return InferenceResult(**arrays, views=ref.views)


def infer_rows(model: ShapeStructureModel, contours: np.ndarray, present: np.ndarray,
               noise_variance: float | None) -> InferenceResult:
    """Infer on the frames with at least one present modelled view; NaN rows for the others.

    contours (N, K_rig, n, 2) px (NaN where missing), present (N, K_rig) bool, noise_variance s^2
    (None = the model's).
    """
    modelled = present[:, list(model.layout_.views)].any(axis=1)
    n = len(contours)
    if modelled.all():
        return model.infer(contours, present, noise_variance=noise_variance, input_views=range(model.n_rig_views_))
    if not modelled.any():
        return nan_result(model, n)
    ok = np.flatnonzero(modelled)
    res = model.infer(contours[ok], present[ok], noise_variance=noise_variance, input_views=range(model.n_rig_views_))
    return merge_results([res, nan_result(model, n - len(ok))], [ok, np.flatnonzero(~modelled)], n)


def run_inference(model_path: Path, input_path: Path, *, out: Path, split: str = "test", save_contours: bool = False,
                  noise_variance: float | None = None, threshold: int = 127) -> str:
    """Load the model, read the input, infer, write outputs; returns a one-line summary."""
    model = load_model(model_path)
    input_path = Path(input_path)
    out = Path(out)
    if out.suffix.lower() not in (".parquet", ".json"):
        raise InferenceInputError(f"{out}: the joints file must end in .parquet or .json")
    if not input_path.is_dir():
        raise InferenceInputError(f"{input_path}: no such folder")
    if is_dataset(input_path):
        frames, contours, present, sample_id = read_dataset_input(model, input_path, split)
    else:
        frames, contours, present, sample_id = read_png_input(model, input_path, threshold)
    modelled = present[:, list(model.layout_.views)]
    empty = ~modelled.any(axis=1)
    if empty.any():
        raise InferenceInputError(
            f"{input_path}: {int(empty.sum())} frame(s) have no usable silhouette in any modelled view "
            f"(first: {frames[np.flatnonzero(empty)[0]]})"
            + ("" if is_dataset(input_path) else f"; a pixel is foreground when brighter than --threshold "
               f"({threshold}; 0/1 mask images are detected): lower it for dim masks")
        )
    result = model.infer(contours, present, noise_variance=noise_variance, input_views=range(model.n_rig_views_))
    rig_names = list(model.rig_.names) if model.rig_ is not None else None
    write_joints(out, frames, result, rig_names, sample_id, str(model_path))
    extra = ""
    if save_contours:
        cpath = sibling(out, ".contours.npz")
        write_contours(cpath, frames, result, rig_names)
        extra = f", contours {cpath}"
    n_missing = int((~modelled).sum())
    return (f"{out}: joints of {len(frames)} frames ({n_missing} missing views marginalised){extra}")
