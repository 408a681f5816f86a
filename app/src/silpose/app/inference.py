"""Contours -> the model -> joints, and the ``silpose infer`` workflow for silhouettes.

:func:`infer_rows` runs :meth:`ShapeStructureModel.infer` on the frames that have at least one
usable modelled view and gives the others NaN rows (the camera-frames path can lose every view of
a frame). :func:`run_inference` is ``silpose infer MODEL INPUT``: INPUT is a dataset folder
(:mod:`.inputs.dataset`) or per-camera silhouette PNG folders (:mod:`.inputs.silhouettes`); it
writes the joints and optionally the reconstructed contours (:mod:`.writers`).

Every frame gets a status (:func:`frame_status`): ``ok``, ``implausible`` (its plausibility
percentile, ``silpose.model.plausibility``, is below the model's threshold: a warning is printed)
or ``no silhouette`` (no usable view: NaN joints).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from silpose.model.hypotheses import TEMPORAL_HYPOTHESES, sequence_answer, temporal_choice
from silpose.model.persistence import load_model
from silpose.model.result import InferenceResult
from silpose.model.shape_model import ShapeStructureModel

from .errors import InferenceInputError
from .inputs.dataset import is_dataset, read_dataset_input
from .inputs.silhouettes import read_png_input
from .writers import sibling, write_contours, write_joints

#: frame statuses written by ``silpose infer`` (column ``status``)
FRAME_OK = "ok"
#: the input is less typical than the model's calibration allows (silpose.model.plausibility): a warning
FRAME_IMPLAUSIBLE = "implausible"
#: no modelled view has a usable silhouette: nothing was inferred (NaN joints)
FRAME_NO_VIEWS = "no silhouette"
#: hypotheses kept per frame by silpose infer
TOP_K = 3


@dataclass(frozen=True)
class InferOptions:
    """How ``silpose infer`` runs the model (:meth:`ShapeStructureModel.infer` arguments).

    noise_variance: s^2 (None = the model's); hypotheses: top-K kept (0 = none); robust: robust
    inference (silpose.model.robust); untangle: simple reconstructed contours; temporal: choose among
    the hypotheses along the frames in order, one track (:func:`silpose.model.hypotheses.temporal_choice`).
    """

    noise_variance: float | None = None
    hypotheses: int = 0
    robust: bool = False
    untangle: bool = False
    temporal: bool = False

    def infer_kwargs(self) -> dict:
        return {"noise_variance": self.noise_variance, "hypotheses": self.hypotheses, "robust": self.robust,
                "untangle": self.untangle}


def nan_result(model: ShapeStructureModel, n: int, options: InferOptions | None = None) -> InferenceResult:
    """An InferenceResult of ``n`` frames without any usable view: NaN everywhere, no view present, and the
    fields a result of ``options`` has (``ShapeStructureModel.empty_result``)."""
    return model.empty_result(n, **(options or InferOptions()).infer_kwargs())


def merge_results(parts: list[InferenceResult], order: list[np.ndarray], n: int) -> InferenceResult:
    """One n-row InferenceResult from ``parts`` whose rows go to indices ``order[i]`` (``InferenceResult.merge``:
    every field any part has is kept)."""
    return InferenceResult.merge(parts, order, n)


def infer_rows(model: ShapeStructureModel, contours: np.ndarray, present: np.ndarray,
               noise_variance: float | None = None, options: InferOptions | None = None) -> InferenceResult:
    """Infer on the frames with at least one present modelled view; NaN rows for the others.

    contours (N, K_rig, n, 2) px (NaN where missing), present (N, K_rig) bool, noise_variance s^2
    (None = the model's; ignored when ``options`` is given), options: the model's inference options.
    """
    opts = options if options is not None else InferOptions(noise_variance=noise_variance)
    kwargs = dict(opts.infer_kwargs(), input_views=range(model.n_rig_views_))
    modelled = present[:, list(model.layout_.views)].any(axis=1)
    n = len(contours)
    if modelled.all():
        return model.infer(contours, present, **kwargs)
    if not modelled.any():
        return nan_result(model, n, opts)
    ok = np.flatnonzero(modelled)
    res = model.infer(contours[ok], present[ok], **kwargs)
    return merge_results([res, nan_result(model, n - len(ok), opts)], [ok, np.flatnonzero(~modelled)], n)


def apply_temporal(result: InferenceResult) -> InferenceResult:
    """Choose among ``result.hypotheses`` along the frames (one track, in order; frames without a view are bridged),
    and answer with the choice: ``result.joints`` becomes each frame's chosen hypothesis where it has one
    (:func:`silpose.model.hypotheses.sequence_answer`; the posterior standard deviations and reconstructed contours
    stay the posterior mean's). Returns ``result``, changed in place."""
    if result.hypotheses is not None:
        result.hypotheses.chosen = temporal_choice(result.hypotheses, valid=result.views_present.any(axis=1))
        result.joints = sequence_answer(result.joints, result.hypotheses)
    return result


def hypotheses_kept(hypotheses: int, temporal: bool) -> int:
    """Hypotheses to keep per frame: ``hypotheses``, at least :data:`silpose.model.hypotheses.TEMPORAL_HYPOTHESES`
    when they are chosen along the frames (``temporal``; 0 stays 0: no hypotheses, the posterior mean)."""
    return max(int(hypotheses), TEMPORAL_HYPOTHESES) if temporal and int(hypotheses) > 0 else int(hypotheses)


def frame_status(result: InferenceResult) -> np.ndarray:
    """(N,) str per frame: :data:`FRAME_NO_VIEWS`, :data:`FRAME_IMPLAUSIBLE` or :data:`FRAME_OK`."""
    status = np.full(len(result.log_marginal), FRAME_OK, dtype=object)
    if result.implausible is not None:
        status[np.asarray(result.implausible, dtype=bool)] = FRAME_IMPLAUSIBLE
    status[~result.views_present.any(axis=1)] = FRAME_NO_VIEWS
    return status


def status_warnings(frames, status: np.ndarray, calibrated: bool) -> list[str]:
    """``warning: ...`` lines for implausible frames and frames without a view (empty when none)."""
    lines = []
    for code, what in ((FRAME_IMPLAUSIBLE, "implausible input (below the plausibility threshold of the model's "
                                           "calibration: not a person, several people, or a broken silhouette?)"),
                       (FRAME_NO_VIEWS, "no usable silhouette in any modelled view (NaN joints)")):
        hit = np.flatnonzero(status == code)
        if hit.size:
            lines.append(f"warning: {hit.size} of {len(status)} frame(s) {what}; first: {frames[hit[0]]}")
    if not calibrated:
        lines.append("warning: the model file has no plausibility calibration (trained before it existed): "
                     "frames are not checked; retrain to enable the check")
    return lines


def run_inference(model_path: Path, input_path: Path, *, out: Path, split: str = "test", save_contours: bool = False,
                  noise_variance: float | None = None, threshold: int = 127, robust: bool = True,
                  temporal: bool = False) -> str:
    """Load the model, read the input, infer, write outputs; returns a summary (``warning:`` lines last).

    Every frame gets the top-3 hypotheses (8 with ``temporal``), a single answer (the posterior mean, unless the most
    probable hypothesis faces the other way: ``silpose.model.hypotheses.single_answer``; with ``temporal``, the
    hypothesis on the Viterbi path over the frames in order: :func:`apply_temporal`), a plausibility percentile and a status; reconstructed
    contours are untangled (simple polygons). A frame without any usable view gets NaN joints and the
    status ``no silhouette`` (it does not stop the run); an input where no frame has one is an error.
    """
    model = load_model(model_path)
    input_path = Path(input_path)
    out = Path(out)
    if out.suffix.lower() not in (".parquet", ".json"):
        raise InferenceInputError(f"{out}: the joints file must end in .parquet or .json")
    if input_path.is_file():
        raise InferenceInputError(f"{input_path}: a file, but the input is a dataset folder or a folder of per-camera "
                                  "folders of silhouette images")
    if not input_path.is_dir():
        raise InferenceInputError(f"{input_path}: no such folder")
    if is_dataset(input_path):
        frames, contours, present, sample_id = read_dataset_input(model, input_path, split)
    else:
        frames, contours, present, sample_id = read_png_input(model, input_path, threshold)
    modelled = present[:, list(model.layout_.views)]
    empty = ~modelled.any(axis=1)
    if empty.all():  # nothing to infer from: an input problem, not a per-frame status
        raise InferenceInputError(
            f"{input_path}: none of the {len(frames)} frame(s) has a usable silhouette in any modelled view"
            + ("" if is_dataset(input_path) else f"; a pixel is foreground when brighter than --threshold "
               f"({threshold}; 0/1 mask images are detected): lower it for dim masks")
        )
    options = InferOptions(noise_variance=noise_variance, hypotheses=hypotheses_kept(TOP_K, temporal), robust=robust,
                           untangle=True, temporal=temporal)
    result = infer_rows(model, contours, present, options=options)
    if temporal:
        apply_temporal(result)
    status = frame_status(result)
    rig_names = list(model.rig_.names) if model.rig_ is not None else None
    write_joints(out, frames, result, rig_names, sample_id, str(model_path), status=status)
    extra = ""
    if save_contours:
        cpath = sibling(out, ".contours.npz")
        write_contours(cpath, frames, result, rig_names)
        extra = f", contours {cpath}"
    n_missing = int((~modelled).sum())
    lines = [f"{out}: joints of {len(frames)} frames ({n_missing} missing views marginalised){extra}"]
    lines += status_warnings(frames, status, getattr(model, "plausibility_", None) is not None)
    return "\n".join(lines)
