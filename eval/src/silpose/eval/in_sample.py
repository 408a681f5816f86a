"""The model on samples it was fitted on: how much of its test error the model itself leaves.

The pose-coverage oracle (:mod:`.coverage`) asks how far the test poses are from the training poses. This asks
the other half: given poses *and* bodies it has seen, how close does the model come? :func:`in_sample_error`
draws as many of the 4-view model's fitted samples as the test split has (``draw_subset`` with the keys
``(seed, IN_SAMPLE_STREAM)``), gives their contours the evaluation's test noise and infers their joints as
``silpose infer`` does by default (robust inference, every view), the same call as the test split's figure
beside it. Both are the paper's pose error (:func:`silpose.shared.metrics.pose_error_cm`).

Reading the three figures together (docs/results.md, "Pose coverage"):

- test error near the oracle, in-sample error far below it: the model generalises as far as the training poses
  reach; more motions (clips) would lower the test error;
- in-sample error near the test error: the model does not hold the poses it was fitted on either; more clips
  alone would not lower it much (capacity, or poses the silhouettes leave ambiguous).

Only rows the model was fitted on are drawn (``EvalData.train_fitted``, set by
:func:`silpose.eval.run.match_training_subset`); when the trainer's held-out split cannot be reproduced there is
no figure (None).
"""

from __future__ import annotations

import numpy as np

from silpose.shared.contours import normalise
from silpose.shared.metrics import pose_error_cm
from silpose.shared.seeds import draw_subset, stream_code

from .noise import apply_noise

__all__ = ["in_sample_error", "IN_SAMPLE_STREAM", "NOISE_ID_OFFSET"]

#: last key of the draw of fitted samples (``draw_subset(n_fit, n, seed, IN_SAMPLE_STREAM)``)
IN_SAMPLE_STREAM = stream_code("in-sample")
#: the noise of fitted row r is drawn as sample ``NOISE_ID_OFFSET + r``: streams apart from the test ids'
NOISE_ID_OFFSET = 1 << 40


def in_sample_error(ev) -> dict | None:
    """The model's pose error on fitted samples against the test split's, under the same inference and noise.

    Args:
        ev: a :class:`silpose.eval.experiments.Evaluation` (its data, model and config: seed, noise).
    Returns:
        ``{"rows": [...] fitted row indices (sorted), "n", "noise", "inference": "robust, every view",
        "in_sample_mean_cm", "in_sample_median_cm", "test_mean_cm", "test_median_cm"}``, or None when the
        fitted rows are unknown.
    """
    d, cfg = ev.data, ev.config
    if d.train_fitted is None or d.train_fitted < 1:
        return None
    rows = draw_subset(d.train_fitted, len(d.test_ids), cfg.seed, IN_SAMPLE_STREAM)
    clean = np.asarray(d.train_contours[rows], np.float64)
    _, centroid, scale = normalise(clean)
    noisy = apply_noise(cfg.noise, clean, NOISE_ID_OFFSET + rows, cfg.seed)
    fitted = ev.model.infer(noisy, centroid=centroid, scale=scale, robust=True)
    test = ev.model.infer(ev.noisy(cfg.noise), centroid=d.test_centroid, scale=d.test_scale, robust=True)
    e_fit = pose_error_cm(fitted.joints, d.train_joints[rows])
    e_test = pose_error_cm(test.joints, d.test_joints)
    return {"rows": rows.tolist(), "n": int(len(rows)), "noise": cfg.noise.label, "inference": "robust, every view",
            "in_sample_mean_cm": float(np.mean(e_fit)), "in_sample_median_cm": float(np.median(e_fit)),
            "test_mean_cm": float(np.mean(e_test)), "test_median_cm": float(np.median(e_test))}
