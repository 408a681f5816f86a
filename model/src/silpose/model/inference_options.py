"""What :meth:`ShapeStructureModel.infer <silpose.model.shape_model.ShapeStructureModel.infer>` adds to a posterior:
plausibility, calibrated mixing, hypotheses and untangled contours.

:func:`inference_plan` reads infer's options (robust settings, the mixing to use, whether the component means are
needed); :func:`complete_result` applies them to the result of the conditioning, in this order: the plausibility
of the observed input (:mod:`silpose.model.plausibility`), the calibrated posterior mean
(:mod:`silpose.model.mixing`), the top hypotheses and the choice among them (:mod:`silpose.model.hypotheses`), the
untangled contours (:mod:`silpose.model.untangle`).
"""

from __future__ import annotations

import numpy as np

from .checks import Inputs
from .hypotheses import consensus_choice, top_hypotheses
from .mixing import Mixing, agreeing_choice, mixed_joints, vote_agreement
from .plausibility import convex_in_every_view
from .posterior import Posterior
from .result import InferenceResult
from .robust import RobustSettings
from .untangle import untangle as untangle_contours

__all__ = ["inference_plan", "complete_result"]


def inference_plan(model, robust: bool | RobustSettings, mixing: Mixing | bool | None,
                   hypotheses: int) -> tuple[RobustSettings | None, Mixing | None, bool]:
    """(robust settings or None, the mixing of the posterior mean or None, whether the conditioning must return the
    component means) of infer's options on the fitted ``model``: ``mixing`` None or True = the model's calibration
    ``mixing_`` when it has one, False = none."""
    settings = RobustSettings() if robust is True else (robust or None)
    mix = getattr(model, "mixing_", None) if mixing is None or mixing is True else (mixing or None)
    want = hypotheses > 0 or mix is not None  # component means (hypotheses) come from the last pass only
    return settings, mix, want


def complete_result(res: InferenceResult, comp: np.ndarray | None, posterior: Posterior, inputs: Inputs, s2: float,
                    *, calibration, mix: Mixing | None, hypotheses: int, consensus: bool,
                    untangle: bool) -> InferenceResult:
    """``res`` (with ``comp``, the component means of the joints (N, M, 19, 3) or None) completed by infer's options
    (module doc); ``calibration`` the model's plausibility calibration or None. Returns ``res``, changed in place."""
    if calibration is not None and calibration.applies_to(s2):
        res.plausibility = calibration.percentile(res.log_marginal, inputs.present)
        # a likelihood percentile cannot flag a smooth blob: convex silhouettes are flagged too
        res.implausible = (calibration.implausible(res.plausibility)
                           | convex_in_every_view(inputs.contours, inputs.present))
    if mix is not None:  # calibrated weights of the posterior mean (silpose.model.mixing)
        agree = vote_agreement(comp, posterior.pair_headings(inputs, s2)) if mix.needs_votes else None
        res.joints = mixed_joints(comp, res.responsibilities, mix.temperature(inputs.present.sum(axis=1)), agree,
                                  mix.vote_weight)
    if hypotheses > 0:
        hyp = top_hypotheses(comp, res.responsibilities, int(hypotheses))
        if consensus and hyp.k > 1:  # votes from the observed input, not the robust pseudo-observations
            hyp.chosen = consensus_choice(hyp, posterior.pair_headings(inputs, s2))
        elif mix is not None:  # the hypothesis facing the calibrated answer's way (silpose.model.mixing)
            hyp.chosen = agreeing_choice(hyp, res.joints)
        res.hypotheses = hyp
    if untangle:
        res.contours_norm, res.contours_px = untangle_contours(res.contours_norm, res.contours_px)
    return res
